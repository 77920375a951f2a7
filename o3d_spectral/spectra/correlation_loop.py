"""The compiled correlation loop, called with the workspaces each thread keeps.

:func:`correlation_peaks` runs :func:`o3d_spectral.spectra.kernels.correlation_peaks_into`
over a stack of rotations of a cloud against one fixed spectrum, outside the GIL. Both the
batched correlation on the CPU
(:class:`o3d_spectral.correlation.backend.CompiledBackend`) and the law's single
correlations (:meth:`o3d_spectral.spectra.target_grid.TargetGrid.correlate`) call it.

Each thread keeps the loop's workspaces (a batch's moving grids, spectra and
correlations) for its next calls: the loop allocates nothing. Fresh large arrays for
every call would have the memory allocator return them to the system and fault them in
again, call after call (over 1,600 page faults a call of 24 rotations on a turntable
pair's 27x30x36 grids, each rotation 1.7x as long as in a call of six; 78,000 in the
climbs of six cluttered scenes).
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from .constants import WORKSPACE_BYTES, WORKSPACES

__all__ = ["Splat", "correlation_peaks", "workspaces"]

_kept = threading.local()


class Splat(NamedTuple):
    """How the loop turns and splats a cloud (the arguments of
    :func:`o3d_spectral.spectra.kernels.turned_splat_into`): rotation ``R`` puts point
    ``p`` at ``u = R p + offset``, continuous voxel coordinates of the moving grid.

    Attributes
    ----------
    points : ndarray, shape (M, 3), float64, C-contiguous
        About the pivot, voxels.
    offset : ndarray, shape (3,), float64
        The pivot on the moving grid, voxels.
    normals : ndarray, shape (M, 3), float64, C-contiguous
        Unit normals (read only when ``culled``; any array of the points' shape otherwise).
    viewpoint : ndarray, shape (3,), float64
        The sensor on the moving grid, voxels (read only when ``culled``).
    culled, two_sided : bool
    min_facing : int
    trilinear, binary : bool
        As for :func:`o3d_spectral.spectra.kernels.turned_splat_into`.
    """

    points: NDArray[np.float64]
    offset: NDArray[np.float64]
    normals: NDArray[np.float64]
    viewpoint: NDArray[np.float64]
    culled: bool
    two_sided: bool
    min_facing: int
    trilinear: bool
    binary: bool

    @classmethod
    def unculled(cls, points: NDArray[np.float64], weighting: str) -> Splat:
        """Every one of ``points`` (voxels of the moving grid, C-contiguous float64)
        splatted where it is: no rotation's pivot, no culling."""
        origin = np.zeros(3)
        return cls(points, origin, points, origin, False, False, 0, weighting == "trilinear",
                   weighting == "binary")


def workspaces(
    batch: int, moving_shape: tuple[int, int, int], shape: tuple[int, int, int]
) -> tuple[NDArray[np.float32], NDArray[np.complex64], NDArray[np.float32]]:
    """This thread's workspaces for batches of ``batch`` moving grids of
    ``moving_shape`` correlated on an FFT grid of ``shape``: the grids, their half spectra
    and their correlations, kept for its next calls (the last :data:`WORKSPACES`
    sizes, at most :data:`WORKSPACE_BYTES` together; the one asked for always)."""
    kept = getattr(_kept, "arrays", None)
    if kept is None:
        kept = _kept.arrays = OrderedDict()
    key = (batch, tuple(moving_shape), tuple(shape))
    arrays = kept.pop(key, None)
    if arrays is None:
        nx, ny, nz = shape
        arrays = (np.empty((batch, *moving_shape), dtype=np.float32),
                  np.empty((batch, nx, ny, nz // 2 + 1), dtype=np.complex64),
                  np.empty((batch, nx, ny, nz), dtype=np.float32))
    kept[key] = arrays
    while len(kept) > 1 and (len(kept) > WORKSPACES or _bytes(kept) > WORKSPACE_BYTES):
        kept.popitem(last=False)
    return arrays


def _bytes(kept: OrderedDict) -> int:
    """The bytes of every workspace in ``kept``."""
    return sum(array.nbytes for arrays in kept.values() for array in arrays)


def correlation_peaks(
    splat: Splat, rotations: NDArray[np.float64], spectrum: NDArray[np.complex64],
    window: NDArray[np.float32], eps: float, searched: tuple[int, int, int],
    overlap: NDArray[np.float64], overlap_at: NDArray[np.int64], *, batch: int,
    moving_shape: tuple[int, int, int], shape: tuple[int, int, int],
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.float32], NDArray[np.float64]]:
    """The correlation peaks of ``splat`` turned by each of ``rotations`` (K, 3, 3),
    ``batch`` grids at a time, on this thread's workspaces
    (:func:`o3d_spectral.spectra.kernels.correlation_peaks_into`, which documents the
    arguments; the arrays it reads are passed as read-only views, one compiled signature
    for every caller).

    Returns
    -------
    values : ndarray, shape (K,), float64
        Each peak, unscaled.
    index : ndarray, shape (K,), int64
        Its flat index in the FFT grid.
    neighbours : ndarray, shape (K, 3, 2), float32
        The correlation one voxel before and after it along each axis.
    overlaps : ndarray, shape (K,), float64
        ``<g, overlap> / |g|`` of each moving grid (0 throughout for an empty ``overlap``).
    """
    from .kernels import correlation_peaks_into  # numba: compiled on first use

    k = len(rotations)
    found = (np.empty(k), np.empty(k, dtype=np.int64), np.empty((k, 3, 2), dtype=np.float32),
             np.zeros(k))
    correlation_peaks_into(*found, splat.points,
                           np.ascontiguousarray(rotations, dtype=np.float64), *splat[1:],
                           _read_only(spectrum), _read_only(window), np.float32(eps),
                           np.asarray(searched, dtype=np.int64), _read_only(overlap),
                           np.asarray(overlap_at, dtype=np.int64),
                           *workspaces(batch, moving_shape, shape))
    return found


def _read_only(values: NDArray) -> NDArray:
    """A read-only view of ``values``."""
    view = values.view()
    view.flags.writeable = False
    return view
