"""Normals' signs between neighbours: consistently oriented, or not, and why not.

Neighbouring points on one surface have normals on the same side of it. Given normals
whose neighbours often point to opposite sides (:func:`sign_disagreement`) are either an
estimate with no orientation step (Open3D's ``estimate_normals()`` flips whole patches),
to be oriented again (:func:`o3d_spectral.io.normals.orient`), or the outward normals of
walls thinner than the points' spacing, whose nearest neighbours lie on either face and
point away from each other (:func:`back_to_back`): a bowl's or a mug's wall, which a
sensor may see from either side (a two-sided cloud, :class:`o3d_spectral.io.cloud.CloudReading`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from .constants import SIGN_DISAGREEMENT, THIN_WALLS

__all__ = [
    "SIGN_DISAGREEMENT", "THIN_WALLS", "sign_disagreement", "back_to_back", "neighbour_signs",
]

#: Points and neighbours :func:`sign_disagreement` looks at.
_SIGN_QUERIES, _SIGN_NEIGHBOURS, _SIGN_TREE_POINTS = 5000, 6, 100_000


def sign_disagreement(points: ArrayLike, normals: ArrayLike) -> float:
    """Share of nearest-neighbour pairs whose normals point to opposite sides.

    Over up to 5000 evenly spread points and those of their 6 nearest neighbours (among
    up to 100,000 points) within 30 degrees of their tangent plane (on the same surface,
    not across a thin wall): near 0 for consistently oriented normals, and well above
    :data:`SIGN_DISAGREEMENT` for normals estimated with no orientation step.

    Parameters
    ----------
    points, normals : array_like, shape (N, 3)
        Metres; unit or zero normals.
    """
    return neighbour_signs(points, normals)[0]


def back_to_back(points: ArrayLike, normals: ArrayLike) -> float:
    """Share of the pairs :func:`sign_disagreement` finds pointing to opposite sides whose
    normals point away from each other (each point behind the other's tangent plane).

    Near 1 for the two faces of walls thinner than the points' spacing, sampled with
    outward normals (at that spacing a point's nearest neighbours lie on either face);
    about 1/3 for normals estimated with no orientation step, whose flipped patches lie
    on one surface (:data:`THIN_WALLS`). 0 when no pair disagrees.

    Parameters
    ----------
    points, normals : array_like, shape (N, 3)
        Metres; unit or zero normals.
    """
    return neighbour_signs(points, normals)[1]


def neighbour_signs(points: ArrayLike, normals: ArrayLike) -> tuple[float, float]:
    """:func:`sign_disagreement` and :func:`back_to_back` from one neighbour search.

    Parameters
    ----------
    points, normals : array_like, shape (N, 3)
        Metres; unit or zero normals.
    """
    opposite, away, along = _neighbour_pairs(points, normals)
    disagree = opposite & along
    disagreement = float(np.mean(opposite[along])) if along.any() else 0.0
    return disagreement, float(np.mean(away[disagree])) if disagree.any() else 0.0


def _neighbour_pairs(
    points: ArrayLike, normals: ArrayLike
) -> tuple[NDArray[np.bool_], NDArray[np.bool_], NDArray[np.bool_]]:
    """For the pairs of :func:`sign_disagreement`, shape (Q, k) each: whose normals point
    to opposite sides, which point away from each other, and which lie on one surface
    (within 30 degrees of the query's tangent plane). Empty when there is no pair."""
    p, n = np.asarray(points, dtype=np.float64), np.asarray(normals, dtype=np.float64)
    stride = int(np.ceil(len(p) / _SIGN_TREE_POINTS))
    p, n = p[::stride], n[::stride]
    k = min(_SIGN_NEIGHBOURS, len(p) - 1)
    if k < 1:
        return (np.zeros((0, 0), dtype=bool),) * 3
    queries = np.linspace(0, len(p) - 1, min(_SIGN_QUERIES, len(p))).astype(np.int64)
    _, nearest = cKDTree(p).query(p[queries], k=k + 1)
    nearest = nearest[:, 1:]
    # component by component (Q, k): NumPy reduces the short last axis of (Q, k, 3) slowly
    n_query = [n[queries, axis][:, None] for axis in range(3)]
    n_near = [n[:, axis][nearest] for axis in range(3)]
    offsets = [p[:, axis][nearest] - p[queries, axis][:, None] for axis in range(3)]
    opposite = _dot(n_query, n_near) < 0.0
    neighbour_ahead = _dot(n_query, offsets)  # of the query's plane
    query_ahead = -_dot(n_near, offsets)  # of the neighbour's plane
    along = np.abs(neighbour_ahead) < 0.5 * np.sqrt(_dot(offsets, offsets))  # not across a wall
    return opposite, (neighbour_ahead < 0.0) & (query_ahead < 0.0), along


def _dot(a: list[NDArray[np.float64]], b: list[NDArray[np.float64]]) -> NDArray[np.float64]:
    """The dot products of two vector arrays given as their three components."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
