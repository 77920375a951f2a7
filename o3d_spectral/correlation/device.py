"""Where the batched correlation runs: a device named in Open3D's manner.

``"CPU:0"`` (the default) runs :class:`~o3d_spectral.correlation.backend.CompiledBackend`
on the CPU's cores; ``"CUDA:n"`` runs :class:`~o3d_spectral.correlation.numpy_api.ArrayBackend`
on CuPy, on the n-th GPU (the ``gpu`` extra: ``pip install 'o3d-spectral[gpu]'``). An
``open3d.core.Device`` names one as well (its ``str`` is the same text), so a caller holding
Open3D's tensors passes their ``device``. CUDA asked for and not usable is refused, never
run on the CPU instead: one line naming the extra, or the reason CuPy gives.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from o3d_spectral.common.extras import require

from .backend import Backend, CompiledBackend
from .numpy_api import ArrayBackend

__all__ = ["Device", "device_backend", "parse_device"]

_PATTERN = re.compile(r"(cpu|cuda)(?::(\d+))?", re.IGNORECASE)


@dataclass(frozen=True)
class Device:
    """A device: ``kind`` ``"CPU"`` or ``"CUDA"``, and its ``index`` (0 for the CPU)."""

    kind: str = "CPU"
    index: int = 0

    def __str__(self) -> str:
        return f"{self.kind}:{self.index}"

    def __repr__(self) -> str:
        return repr(str(self))

    @property
    def gpu(self) -> bool:
        """Whether it is a GPU (the dense search is then the default)."""
        return self.kind == "CUDA"


def parse_device(device: object | None, name: str = "device") -> Device:
    """``device`` (None, ``"CPU:0"``, ``"CUDA:1"``, ``"cuda"``, or an
    ``open3d.core.Device``) as a :class:`Device`; ``TypeError`` / ``ValueError`` naming
    ``name`` for anything else."""
    if device is None:
        return Device()
    if isinstance(device, Device):
        return device
    is_open3d = type(device).__module__.startswith("open3d")
    if not isinstance(device, str) and not is_open3d:
        raise TypeError(f"{name} must be a device such as 'CPU:0' or 'CUDA:0' (or an "
                        f"open3d.core.Device), got {type(device).__qualname__}")
    match = _PATTERN.fullmatch(str(device).strip())
    if match is None:
        raise ValueError(f"{name} must be 'CPU:0' or 'CUDA:<n>' (or an open3d.core.Device), "
                         f"got {str(device)!r}")
    kind, index = match.group(1).upper(), int(match.group(2) or 0)
    if kind == "CPU" and index != 0:
        raise ValueError(f"{name}: there is one CPU device, 'CPU:0'; got {str(device)!r}")
    return Device(kind, index)


def device_backend(device: Device) -> Backend:
    """The backend that runs the batched correlation on ``device``.

    Raises
    ------
    MissingExtraError
        For a CUDA device without CuPy (the ``gpu`` extra).
    ValueError
        For a CUDA device CuPy cannot use: none found, an index past the last, no driver.
    """
    if not device.gpu:
        return CompiledBackend()
    cupy = require("cupy", f"device='{device}'")
    try:
        count = cupy.cuda.runtime.getDeviceCount()
    except Exception as error:  # no driver, no device: CUDA's own error, on one line
        reason = " ".join(str(error).split()) or type(error).__name__
        raise ValueError(f"device='{device}' is not usable: {reason}") from None
    if device.index >= count:
        raise ValueError(f"device='{device}' does not exist: {count} CUDA device"
                         f"{'s' if count != 1 else ''} found")
    return ArrayBackend(cupy, device=device.index)
