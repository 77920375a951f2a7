"""Exact reductions of point and vector arrays (N, 3), one column at a time, and a ball test.

NumPy reduces an (N, 3) array across its three columns, or down each of them at once,
through a slow strided loop: for a 55k-point depth capture, ``points.min(axis=0)`` takes
about 3 ms and ``np.linalg.norm(normals, axis=1)`` 2 ms, against 0.07 and 0.3 ms column
by column. These give the same values to the bit (a minimum is exact; three terms are
summed in the same order) at the columns' cost.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["bounds", "largest_side", "lengths", "every", "some", "known", "in_ball"]


def bounds(points: ArrayLike) -> tuple[NDArray, NDArray]:
    """``points.min(axis=0), points.max(axis=0)`` of ``points`` (N, D)."""
    p = np.asarray(points)
    return (np.array([p[:, k].min() for k in range(p.shape[1])]),
            np.array([p[:, k].max() for k in range(p.shape[1])]))


def largest_side(points: ArrayLike) -> float:
    """``np.max(np.ptp(points, axis=0))``: the largest side of the box holding ``points``
    (N, D)."""
    lower, upper = bounds(points)
    return float(np.max(upper - lower))


def lengths(vectors: NDArray[np.floating]) -> NDArray[np.floating]:
    """``np.linalg.norm(vectors, axis=1)`` of ``vectors`` (N, 3)."""
    x, y, z = vectors[:, 0], vectors[:, 1], vectors[:, 2]
    return np.sqrt(x * x + y * y + z * z)


def every(mask: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """``np.all(mask, axis=1)`` of ``mask`` (N, 3)."""
    return mask[:, 0] & mask[:, 1] & mask[:, 2]


def some(mask: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """``np.any(mask, axis=1)`` of ``mask`` (N, 3)."""
    return mask[:, 0] | mask[:, 1] | mask[:, 2]


def known(normals: NDArray[np.floating]) -> NDArray[np.bool_]:
    """The rows of ``normals`` (N, 3) that hold a normal: unit vectors, not the zero rows
    that mark a point whose normal is unknown."""
    x, y, z = normals[:, 0], normals[:, 1], normals[:, 2]
    return x * x + y * y + z * z > 0.5


def in_ball(
    points: NDArray[np.float64], centre: NDArray[np.float64], radius: float
) -> NDArray[np.bool_]:
    """Whether each of ``points`` (N, 3) lies within ``radius`` of ``centre`` (3,), all in
    metres: (N,), squared distances against the squared radius."""
    offsets = points - centre
    return np.einsum("ij,ij->i", offsets, offsets) <= radius * radius
