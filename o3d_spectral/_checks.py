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


def check_transformation(init: object, name: str = "init") -> NDArray[np.float64]:
    """``init`` as a 4x4 float64 array; ``ValueError`` unless it is a finite rigid
    transformation."""
    M = np.asarray(init, dtype=np.float64)
    if M.shape != (4, 4):
        raise ValueError(f"{name} must be a 4x4 matrix, got shape {M.shape}")
    R = M[:3, :3]
    finite = bool(np.all(np.isfinite(M)))
    rigid = finite and np.allclose(R.T @ R, np.eye(3), atol=1e-6) and abs(
        np.linalg.det(R) - 1.0) < 1e-6 and np.allclose(M[3], [0.0, 0.0, 0.0, 1.0])
    if not rigid:
        raise ValueError(f"{name} must be a finite rigid transformation (rotation + translation)")
    return M


def check_point(name: str, value: object) -> tuple[float, float, float] | None:
    """``value`` must be None or three finite coordinates (metres); returns a tuple."""
    if value is None:
        return None
    if isinstance(value, str):
        raise TypeError(f"{name} must be three coordinates in metres, got {value!r}")
    try:
        point = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be three coordinates in metres, got {value!r}") from None
    if point.shape != (3,):
        raise ValueError(f"{name} must be three coordinates in metres, got {value!r}")
    if not np.all(np.isfinite(point)):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return (float(point[0]), float(point[1]), float(point[2]))
