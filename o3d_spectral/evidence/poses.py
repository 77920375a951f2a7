"""When two poses are distinct, and how far the best pose leads its distinct rivals."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..spectra import so3
from .constants import DISTINCT_ANGLE

__all__ = ["DISTINCT_ANGLE", "distinct", "confidence"]


def distinct(a: NDArray[np.float64], b: NDArray[np.float64]) -> bool:
    """Whether the poses ``a`` and ``b`` (4, 4, or their rotations (3, 3)) turn a cloud
    over :data:`DISTINCT_ANGLE` apart: the angle of ``a^T b``'s rotation."""
    return so3.rotation_angle(a[:3, :3].T @ b[:3, :3]) > DISTINCT_ANGLE


def confidence(ranked: list[tuple[float, NDArray[np.float64]]]) -> float:
    """Best score minus the best score of a pose :func:`distinct` from the best; the best
    score when none is. ``ranked``: (score, 4x4 transformation), best first."""
    best_score, best = ranked[0]
    for score, other in ranked[1:]:
        if distinct(other, best):
            return best_score - score
    return best_score
