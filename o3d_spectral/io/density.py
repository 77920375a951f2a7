"""Dense clouds read at the cost of their voxels: one point per quarter-voxel cell.

A scanner or a depth camera can put hundreds of points in each voxel (a 1.3-megapixel
depth map of an object 45 cm away: 280 per 8 mm voxel). The method reads a surface a
quarter voxel apart (its normals are estimated there, :func:`o3d_spectral.io.cloud.prepare`),
so such a cloud holds no more for it than one point per quarter-voxel cell: every stage of
a call (the preparation, the confirmation, the polish, the scoring) is run on those
points, the first of each cell in the cloud's order. They are actual points of the
cloud, so that indices into them map back to the caller's (``correspondence_set``).

A cloud is *dense* when it averages over :data:`DENSE_PER_CELL` points per occupied
cell; clouds at the usual densities (the suites' views, raw laser scans at 25-30 points
per voxel) are read whole.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .cloud import MIN_POINTS, CloudArrays
from .constants import CELL, DENSE_PER_CELL, MAX_CELLS
from .rows import bounds

__all__ = ["CELL", "DENSE_PER_CELL", "MAX_CELLS", "first_per_cell", "read_at_voxels"]


def first_per_cell(points: NDArray[np.float64], cell: float) -> NDArray[np.int64]:
    """Indices (ascending) of the first of the points (N, 3) in each cube of ``cell``
    metres: actual points, so that indices into the subset map back to the cloud."""
    if len(points) == 0:
        return np.zeros(0, dtype=np.int64)
    lower, upper = bounds(points)
    if not np.max(upper - lower) < MAX_CELLS * cell:  # cells finer than int64 keys hold
        return np.sort(np.unique(points, axis=0, return_index=True)[1])  # distinct points
    keys = np.floor((points - lower) / cell).astype(np.int64)
    span = bounds(keys)[1] + 1
    if float(span[0]) * float(span[1]) * float(span[2]) < 2.0**62:  # one int64 per cell
        flat = keys[:, 0] + span[0] * (keys[:, 1] + span[1] * keys[:, 2])
        first = np.unique(flat, return_index=True)[1]
    else:  # a cloud over ~4e6 cells a side: rows
        first = np.unique(keys, axis=0, return_index=True)[1]
    return np.sort(first)


def read_at_voxels(
    arrays: CloudArrays, voxel_size: float
) -> tuple[CloudArrays, NDArray[np.int64] | None]:
    """``arrays`` as a call reads it at ``voxel_size`` (metres): a dense cloud's first
    point (and normal) in each cell of :data:`CELL` voxels, and those points' indices in
    ``arrays``; any other cloud itself, and None."""
    lower, upper = bounds(arrays.points)
    if not np.max(upper - lower) < MAX_CELLS * CELL * voxel_size:
        return arrays, None  # no cell holds two points (a voxel size the grids refuse)
    keep = first_per_cell(arrays.points, CELL * voxel_size)
    if len(arrays.points) <= DENSE_PER_CELL * len(keep) or len(keep) < MIN_POINTS:
        # not dense; or too few cells to register, refused by prepare with its own count
        return arrays, None
    normals = None if arrays.normals is None else arrays.normals[keep]
    return CloudArrays(arrays.points[keep], normals), keep
