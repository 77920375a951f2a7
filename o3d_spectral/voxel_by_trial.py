"""A voxel size chosen by trial: registered at a few sizes about the rule's, the most
confident kept.

:func:`o3d_spectral.suggest_voxel_size` reads a size off the clouds' point spacing and
extent; on the benchmarks it registers as often as the sizes chosen by hand over all,
but less often on single groups (dragon scans 72-120 degrees apart, RGB-D crops of small
objects), where success turns on the size. :func:`voxel_trial` registers
at the rule's size first and, unless that pose is confidently right, at the other sizes
of :data:`VOXEL_LADDER` in turn, and keeps the pose whose calibrated
``result.confidence`` (the probability that it is right) is highest. Its cost is one
global registration where the first is confident, up to ``len(ladder)`` otherwise.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from .registration import registration_spectral_global
from .result import SpectralRegistrationResult
from .voxel import suggest_voxel_size

__all__ = ["VoxelTrial", "voxel_trial", "VOXEL_LADDER", "CONFIDENT"]

#: Factors of :func:`~o3d_spectral.suggest_voxel_size`'s size tried, in this order: the
#: rule's size, a finer one (dragon scans 72-120 degrees apart were lost at the rule's
#: 6.3-7.2 mm and right at 5 mm), a coarser one (a YCB-Video crop lost at 3.6 mm, right at
#: 5-8 mm). Chosen among ladders of 1-4 factors of 0.6-1.9 and early stops at 0.8-0.95 on
#: one set of suite instances and real rotations; ``eval/voxel_advice.py --trial`` (126
#: cases) gives it the rule's success overall (docs/conventions.md).
VOXEL_LADDER = (1.0, 0.75, 1.4)
#: A trial at least this confident ends the ladder: its pose is kept.
CONFIDENT = 0.9


@dataclass
class VoxelTrial:
    """The kept registration of :func:`voxel_trial` and what was tried.

    Attributes
    ----------
    voxel_size : float
        The kept registration's voxel size, metres.
    result : SpectralRegistrationResult
        The kept registration.
    tried : list of (float, float)
        Each size tried (metres) and its registration's ``confidence``, in order.
    """

    voxel_size: float
    result: SpectralRegistrationResult
    tried: list[tuple[float, float]] = field(default_factory=list)


def voxel_trial(
    source: object, target: object, *, ladder: Sequence[float] = VOXEL_LADDER,
    **options: object,
) -> VoxelTrial:
    """Register ``source`` to ``target`` at a voxel size chosen by trial.

    The sizes are :func:`~o3d_spectral.suggest_voxel_size`'s times each factor of
    ``ladder``, in order; each is registered by
    :func:`~o3d_spectral.registration_spectral_global` until one's ``confidence``
    reaches :data:`CONFIDENT`, and the most confident registration is kept (the first of
    equals).

    Parameters
    ----------
    source, target : PointCloud, tensor PointCloud or ndarray
        As for :func:`~o3d_spectral.registration_spectral_global` (metres).
    ladder : sequence of float
        Positive factors of the rule's size, the first tried first.
    **options
        Keyword arguments of :func:`~o3d_spectral.registration_spectral_global`
        (``option``, ``search``, ``cloud``, ``refinement``, ...), the same at every size.

    Returns
    -------
    VoxelTrial

    Raises
    ------
    ValueError
        For an empty ``ladder`` or a factor that is not a positive number, and as
        :func:`~o3d_spectral.suggest_voxel_size` and the registration call.

    Examples
    --------
    >>> trial = o3d_spectral.voxel_trial(model, scan)  # doctest: +SKIP
    >>> trial.voxel_size, trial.result.confidence  # doctest: +SKIP
    """
    factors = [float(f) for f in ladder]
    if not factors or not all(np.isfinite(f) and f > 0.0 for f in factors):
        raise ValueError(f"ladder must hold positive factors, got {list(ladder)!r}")
    rule = suggest_voxel_size(source, target)
    kept: VoxelTrial | None = None
    tried: list[tuple[float, float]] = []
    for factor in factors:
        voxel_size = rule * factor
        result = registration_spectral_global(source, target, voxel_size, **options)
        tried.append((voxel_size, result.confidence))
        if kept is None or result.confidence > kept.result.confidence:
            kept = VoxelTrial(voxel_size, result)
        if result.confidence >= CONFIDENT:
            break
    kept.tried = tried
    return kept
