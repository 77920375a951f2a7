"""Validation of settings, in one place: each check names the field and shows the value.

A value of the wrong type raises ``TypeError`` (a string where a flag is expected, a
float where a count is); a NaN, an infinity where a finite number is needed, or a value
out of range raises ``ValueError``.
"""

from __future__ import annotations

import numbers
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from .constants import MAX_VOXELS_ACROSS, RIGID_TOLERANCE


def check_bool(name: str, value: object) -> None:
    """``value`` must be a bool (``True``/``False``, or numpy's)."""
    if not isinstance(value, bool | np.bool_):
        raise TypeError(f"{name} must be True or False, got {value!r}")


def check_choice(name: str, value: object, choices: Sequence[object]) -> None:
    """``value`` must be one of ``choices``."""
    if not isinstance(value, str | type(None)) or value not in choices:
        raise ValueError(f"{name} must be one of {tuple(choices)}, got {value!r}")


def _bounds(
    name: str, value: float, low: float | None, high: float | None, low_open: bool,
    high_name: str | None = None,
) -> None:
    if low is not None and (value <= low if low_open else value < low):
        relation = ">" if low_open else ">="
        raise ValueError(f"{name} must be {relation} {low}, got {value}")
    if high is not None and value > high:
        limit = f"{high_name} ({high})" if high_name else f"{high}"
        raise ValueError(f"{name} must be <= {limit}, got {value}")


def check_int(
    name: str, value: object, *, low: int | None = None, high: int | None = None,
    optional: bool = False, high_name: str | None = None,
) -> None:
    """``value`` must be an integer (not a bool, not a float) in ``[low, high]``; None
    too when ``optional``."""
    if value is None and optional:
        return
    if isinstance(value, bool | np.bool_) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{name} must be an integer, got {value!r}")
    _bounds(name, int(value), low, high, False, high_name)


def check_number(
    name: str, value: object, *, low: float | None = None, high: float | None = None,
    low_open: bool = False, optional: bool = False,
) -> None:
    """``value`` must be a finite real number (not a bool) with ``low <= value <= high``
    (``low < value`` when ``low_open``); None too when ``optional``."""
    if value is None and optional:
        return
    if isinstance(value, bool | np.bool_) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name} must be a number, got {value!r}")
    if not np.isfinite(float(value)):
        raise ValueError(f"{name} must be finite, got {value}")
    _bounds(name, float(value), low, high, low_open)


def check_instance(name: str, value: object, cls: type, *, optional: bool = True) -> None:
    """``value`` must be a ``cls`` (or None when ``optional``): another library's settings
    object of a similar name (Open3D's ``ICPConvergenceCriteria``) is refused here."""
    if (value is None and optional) or isinstance(value, cls):
        return
    raise TypeError(
        f"{name} must be an o3d_spectral.{cls.__name__}"
        f"{' or None' if optional else ''}, got {type(value).__module__}."
        f"{type(value).__qualname__}"
    )


def shown(value: object, limit: int = 60) -> str:
    """``repr(value)`` on one line, cut to ``limit`` characters, for error messages."""
    text = " ".join(repr(value).split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def real_array(name: str, value: object) -> NDArray[np.float64]:
    """``value`` as a float64 array, refused by ``name`` unless it holds real numbers.

    ``TypeError`` for a string, a bool or complex array, or objects that are not real
    numbers (numpy would read bools as 0/1 and drop an imaginary part with only a
    warning); an Open3D tensor is read through ``.numpy()``.
    """
    if isinstance(value, str | bytes):
        raise TypeError(f"{name} must be an array of real numbers, got the string {value!r}")
    if hasattr(value, "numpy") and type(value).__module__.startswith("open3d"):
        value = value.numpy()  # open3d.core.Tensor
    try:
        array = np.asarray(value)
    except (TypeError, ValueError) as error:  # ragged nesting
        raise ValueError(f"{name} must be an array of real numbers ({error})") from None
    if array.dtype.kind == "O":  # Fractions, Decimals, or anything else: each must be real
        if not all(isinstance(x, numbers.Real) and not isinstance(x, bool | np.bool_)
                   for x in array.ravel()):
            raise TypeError(f"{name} must be an array of real numbers, got "
                            f"{type(value).__qualname__} {shown(value)}")
        try:
            array = array.astype(np.float64)
        except OverflowError:  # an int beyond float64: not a finite number
            raise ValueError(f"{name} must be finite, got {shown(value)}") from None
    if array.dtype.kind not in "fiu":
        kind = {"b": "bool", "c": "complex", "U": "string", "S": "bytes"}.get(
            array.dtype.kind, str(array.dtype))
        raise TypeError(f"{name} must be an array of real numbers, got a {kind} array")
    return np.array(array, dtype=np.float64)  # a copy: the caller's array is never touched


def check_transformation(init: object, name: str = "init") -> NDArray[np.float64]:
    """``init`` as a new 4x4 float64 rigid transformation.

    Type first (``TypeError`` for anything but real numbers: a string, a scipy
    ``Rotation``, a complex or bool array), then value (``ValueError`` for a shape other
    than 4x4, a NaN or infinity, a last row other than ``0 0 0 1``, a reflection, or a
    rotation block further than :data:`RIGID_TOLERANCE` from orthonormal). A rotation
    block within the tolerance (a pose written with a few decimals) is replaced by the
    nearest rotation (polar decomposition), so the pose used is exactly rigid.
    """
    M = real_array(name, init)
    if M.shape != (4, 4):
        raise ValueError(f"{name} must be a 4x4 matrix, got shape {M.shape}")
    if not np.all(np.isfinite(M)):
        raise ValueError(f"{name} must be finite, got {M.tolist()}")
    if np.max(np.abs(M[3] - [0.0, 0.0, 0.0, 1.0])) > RIGID_TOLERANCE:
        raise ValueError(f"{name} must be a rigid transformation: its last row must be "
                         f"0 0 0 1, got {M[3].tolist()}")
    R = M[:3, :3]
    deviation = float(np.max(np.abs(R.T @ R - np.eye(3))))
    if deviation > RIGID_TOLERANCE or np.linalg.det(R) <= 0.0:
        what = "a reflection" if np.linalg.det(R) <= 0.0 else f"{deviation:.2g} from orthonormal"
        raise ValueError(f"{name} must be a rigid transformation (rotation + translation): "
                         f"its rotation block is {what} (tolerance {RIGID_TOLERANCE:g})")
    U, _, Vt = np.linalg.svd(R)
    M[:3, :3] = U @ Vt  # det > 0 and near-orthonormal: the nearest rotation
    M[3] = [0.0, 0.0, 0.0, 1.0]
    return M


def check_voxel_size(value: object, name: str = "voxel_size") -> float:
    """``value`` as a float: a real number (not a bool), finite and positive, metres.

    ``TypeError`` for any other type (a string, None, a list, complex, ``Decimal``);
    ``ValueError`` for NaN, infinity, zero or a negative number. (Too small for the
    clouds is refused where their size is known: :class:`o3d_spectral.SpectralStepper`.)
    """
    if isinstance(value, bool | np.bool_) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name} must be a number of metres (int or float), got "
                        f"{type(value).__qualname__} {shown(value)}")
    try:
        size = float(value)
    except OverflowError:
        size = float("inf")
    if not (np.isfinite(size) and size > 0.0):
        raise ValueError(f"{name} must be a positive number of metres (finite), got {shown(value)}")
    return size


def check_voxel_span(voxel_size: float, extent: float, name: str,
                     setting: str = "voxel_size") -> None:
    """``ValueError`` naming ``setting`` (``voxel_size``) when the cloud ``name``,
    ``extent`` metres across, would span under 4 voxels of it (too few to register) or
    over :data:`MAX_VOXELS_ACROSS` (no grid could hold it)."""
    if extent < 4 * voxel_size:
        raise ValueError(
            f"{setting}={voxel_size:g} m is too large: {name} spans {extent:.4g} m, under 4 "
            f"voxels of it: use a smaller {setting} (check the clouds are in metres)"
        )
    if extent > MAX_VOXELS_ACROSS * voxel_size:
        raise ValueError(
            f"{setting}={voxel_size:g} m is too small: {name} spans {extent:.4g} m, over "
            f"{MAX_VOXELS_ACROSS} voxels (no voxel grid could hold it; check the clouds "
            "are in metres)"
        )


def check_reach(init: NDArray[np.float64], source: NDArray[np.float64],
                target: NDArray[np.float64], voxel_size: float, name: str = "init") -> None:
    """``ValueError`` naming ``init`` when it places the ``source`` points (n, 3) so far
    from the ``target`` points (m, 3), metres, that one grid of ``voxel_size`` over both
    would span over :data:`MAX_VOXELS_ACROSS` voxels."""
    placed = source @ init[:3, :3].T + init[:3, 3]
    extent = float(np.max(np.maximum(placed.max(0), target.max(0))
                          - np.minimum(placed.min(0), target.min(0))))
    if not extent <= MAX_VOXELS_ACROSS * voxel_size:
        raise ValueError(
            f"{name} places the source so far from the target that the two span "
            f"{extent:.4g} m, over {MAX_VOXELS_ACROSS} voxels of voxel_size={voxel_size:g} m "
            f"(no voxel grid could hold both; check {name}'s translation is in metres), "
            f"got translation {init[:3, 3].tolist()}"
        )


def check_point(name: str, value: object) -> tuple[float, float, float] | None:
    """``value`` must be None or three finite coordinates (metres); returns a tuple."""
    if value is None:
        return None
    if isinstance(value, str):
        raise TypeError(f"{name} must be three coordinates in metres, got {value!r}")
    try:
        point = real_array(name, value)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be three coordinates in metres, got {shown(value)}"
                        ) from None
    if point.shape != (3,):
        raise ValueError(f"{name} must be three coordinates in metres, got {shown(value)}")
    if not np.all(np.isfinite(point)):
        raise ValueError(f"{name} must be finite, got {shown(value)}")
    return (float(point[0]), float(point[1]), float(point[2]))
