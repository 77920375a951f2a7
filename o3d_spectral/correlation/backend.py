"""What the batched phase correlation asks of an array library, and two answers.

:class:`~o3d_spectral.correlation.batched.BatchedCorrelation` runs one pipeline over a
stack of rotations: splat the turned cloud on the moving grid, transform it (zero-padded
to the FFT shape), whiten its cross-power against the fixed spectrum, transform back,
read each grid's peak. A :class:`Backend` runs that pipeline on its arrays
(:meth:`Backend.correlate`), and the splat and forward transform alone for the fixed grid:

* :class:`CompiledBackend`: NumPy on the CPU. The whole pipeline over a run of batches is
  one compiled loop (numba; pocketfft's transforms compiled in through rocket-fft,
  skipping the lines the zero padding leaves empty): one call per run, the GIL released
  for all of it, so that runs on threads use every core and no worker waits on another's
  Python. Batches fill about a core's cache (:data:`BATCH_BYTES`): at the voxel's grid of
  a 0.2 m scan, one grid.
* :class:`~o3d_spectral.correlation.numpy_api.ArrayBackend`: any library with NumPy's API
  (NumPy, CuPy) over whole stacks in plain array operations: the reference the compiled
  loops are tested against, and the path a GPU library runs.

All grids are single precision, as the search's other phase correlations: it halves the
transforms' time, and the peak heights agree with
:meth:`o3d_spectral.SpectralStepper.locate`'s to about 1e-7 (``tests/test_ascent.py``
holds them to 1e-5).
"""

from __future__ import annotations

import threading
from abc import ABC, abstractmethod
from collections import OrderedDict
from types import ModuleType
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from .constants import BATCH_BYTES, WORKSPACES
from .turned import TurnedCloud

__all__ = ["Backend", "CompiledBackend", "Fixed", "Found", "array_backend", "BATCH_BYTES"]


Array = object  # an array of the backend's library


class Fixed(NamedTuple):
    """What a correlation holds of its fixed grid on the backend.

    Attributes
    ----------
    spectrum : array, shape (nx, ny, nz // 2 + 1), complex64
        The fixed grid's half spectrum on :attr:`shape` (:meth:`Backend.spectrum`).
    window : array, shape (nx, ny, nz // 2 + 1), float32
        The Gaussian window on the cross-power spectrum.
    eps : float
        Cross-power terms under ``eps`` times the largest are not whitened.
    moving_shape, shape : tuple of 3 int
        The moving grid and the FFT grid.
    searched : tuple of 3 int
        The peak is sought at indices below these per axis (:attr:`shape`: everywhere).
    overlap : array, shape ``moving_shape`` or (0, 0, 0), float64
        The fixed grid on the moving grid's cells, which each turned moving grid is
        compared with before any shift (:attr:`Found.overlaps`); empty: not compared.
    """

    spectrum: Array
    window: Array
    eps: float
    moving_shape: tuple[int, int, int]
    shape: tuple[int, int, int]
    searched: tuple[int, int, int]
    overlap: Array


class Found(NamedTuple):
    """What :meth:`Backend.correlate` reads of each rotation's correlation, on the host.

    Attributes
    ----------
    values : ndarray, shape (K,), float64
        The peak (unscaled).
    index : ndarray, shape (K,), int64
        Its flat index in the FFT grid (the first of equals in C order).
    neighbours : ndarray, shape (K, 3, 2), float32
        The correlation one voxel before and after the peak along each axis, wrapping
        around the FFT grid.
    overlaps : ndarray, shape (K,), float64
        ``<g, overlap> / |g|`` of the turned moving grid ``g`` and :attr:`Fixed.overlap`
        (0 for an empty grid; 0 throughout where no overlap is asked).
    """

    values: NDArray[np.float64]
    index: NDArray[np.int64]
    neighbours: NDArray[np.float32]
    overlaps: NDArray[np.float64]


class Backend(ABC):
    """The batched correlation's pipeline on one array library.

    Attributes
    ----------
    xp : module
        The array library (``numpy``, ``cupy``).
    threaded : bool
        Whether runs of batches go side by side on threads (a CPU library that releases
        the GIL) rather than one after the other (a GPU, which works on a whole batch).
    """

    xp: ModuleType
    threaded: bool

    def asarray(self, values: NDArray, dtype: type) -> Array:
        """``values`` as an array of the backend (copied to its device)."""
        return self.xp.asarray(values, dtype=dtype)

    def to_numpy(self, values: Array) -> NDArray:
        """An array of the backend as a NumPy array (copied from its device)."""
        return getattr(self.xp, "asnumpy", np.asarray)(values)

    def batch_size(self, shape: tuple[int, int, int]) -> int:
        """Rotations correlated together on an FFT grid of ``shape``."""
        return max(1, BATCH_BYTES // (4 * int(np.prod(shape))))

    @abstractmethod
    def splat(
        self, cloud: TurnedCloud, rotations: NDArray[np.float64], grid: tuple[int, int, int]
    ) -> Array:
        """``cloud`` turned by each of ``rotations`` (B, 3, 3) and splatted on a moving
        grid of shape ``grid``: (B, *grid), single precision."""

    def spectrum(self, grid: NDArray, shape: tuple[int, int, int]) -> Array:
        """The half spectrum of one grid zero-padded to ``shape``, on the backend,
        C-contiguous."""
        return self.forward(self.asarray(grid[None], self.xp.float32), shape)[0].copy()

    @abstractmethod
    def forward(self, grids: Array, shape: tuple[int, int, int]) -> Array:
        """Half spectra (B, nx, ny, nz // 2 + 1) of ``grids`` (B, ...) zero-padded from
        their corner to ``shape``."""

    @abstractmethod
    def correlate(
        self, cloud: TurnedCloud, rotations: NDArray[np.float64], batch: int, fixed: Fixed
    ) -> Found:
        """The pipeline over ``rotations`` (K, 3, 3), ``batch`` grids at a time: each
        turned grid's correlation peak against ``fixed`` within ``fixed.searched``, where
        it lies and its neighbours, and the grid's overlap with ``fixed.overlap``, on the
        host. Each grid is computed alone, whatever the batch; ``MemoryError`` where a
        batch does not fit."""


class CompiledBackend(Backend):
    """NumPy on the CPU: the whole pipeline as one compiled loop
    (:func:`o3d_spectral.spectra.kernels.correlation_peaks_into`) over a run of batches on
    the calling thread, outside the GIL (see the module docstring).

    Each thread keeps the loop's workspaces (a batch's moving grids, spectra and
    correlations) for its next runs: the loop allocates nothing. Fresh large arrays for
    every call would have the memory allocator return them to the system and fault them
    in again, call after call (over 1,600 page faults a call of 24 rotations on a
    turntable pair's 27x30x36 grids, each rotation 1.7x as long as in a call of six).
    """

    xp = np
    threaded = True

    def __init__(self) -> None:
        self._local = threading.local()

    def __getstate__(self) -> dict:
        return {}  # the workspaces stay with their threads (a copy starts without)

    def __setstate__(self, state: dict) -> None:
        self.__init__()

    def _workspaces(self, batch: int, fixed: Fixed) -> tuple[NDArray, NDArray, NDArray]:
        """This thread's workspaces for batches of ``batch`` grids against ``fixed``: the
        moving grids, their half spectra and their correlations, kept for its next runs
        (the last :data:`WORKSPACES` sizes)."""
        kept = getattr(self._local, "workspaces", None)
        if kept is None:
            kept = self._local.workspaces = OrderedDict()
        key = (batch, fixed.moving_shape, fixed.shape)
        arrays = kept.pop(key, None)
        if arrays is None:
            nx, ny, nz = fixed.shape
            arrays = (np.empty((batch, *fixed.moving_shape), dtype=np.float32),
                      np.empty((batch, nx, ny, nz // 2 + 1), dtype=np.complex64),
                      np.empty((batch, nx, ny, nz), dtype=np.float32))
        kept[key] = arrays
        if len(kept) > WORKSPACES:
            kept.popitem(last=False)
        return arrays

    def splat(
        self, cloud: TurnedCloud, rotations: NDArray[np.float64], grid: tuple[int, int, int]
    ) -> NDArray[np.float32]:
        from ..spectra.kernels import turned_splat_into

        grids = np.zeros((len(rotations), *grid), dtype=np.float32)
        turned_splat_into(grids, cloud.points, np.ascontiguousarray(rotations, dtype=np.float64),
                          cloud.offset, *_culling(cloud))
        return grids

    def forward(
        self, grids: NDArray[np.float32], shape: tuple[int, int, int]
    ) -> NDArray[np.complex64]:
        """:meth:`Backend.forward`, transforming only the lines the grids reach
        (:func:`o3d_spectral.spectra.fft.padded_forward`)."""
        from ..spectra.fft import padded_forward

        return padded_forward(grids, shape)

    def correlate(
        self, cloud: TurnedCloud, rotations: NDArray[np.float64], batch: int, fixed: Fixed
    ) -> Found:
        from ..spectra.kernels import correlation_peaks_into

        k = len(rotations)
        found = Found(np.empty(k), np.empty(k, dtype=np.int64),
                      np.empty((k, 3, 2), dtype=np.float32), np.zeros(k))
        correlation_peaks_into(*found, cloud.points,
                               np.ascontiguousarray(rotations, dtype=np.float64), cloud.offset,
                               *_culling(cloud), fixed.spectrum, fixed.window,
                               np.float32(fixed.eps), np.asarray(fixed.searched, dtype=np.int64),
                               fixed.overlap, *self._workspaces(batch, fixed))
        return found


def _culling(cloud: TurnedCloud) -> tuple:
    """The compiled splat's arguments after the offset: normals, viewpoint, culled,
    two_sided, min_facing, trilinear, binary (the points and offset stand in for the
    normals and viewpoint of a cloud that is not culled)."""
    normals = cloud.normals if cloud.culled else cloud.points
    viewpoint = cloud.viewpoint if cloud.culled else cloud.offset
    return (normals, viewpoint, cloud.culled, cloud.two_sided, cloud.min_facing,
            cloud.weighting == "trilinear", cloud.weighting == "binary")


def array_backend(backend: Backend | None = None) -> Backend:
    """``backend``, or the default: :class:`CompiledBackend` (NumPy on the CPU)."""
    if backend is None:
        return CompiledBackend()
    if not isinstance(backend, Backend):
        raise TypeError(f"backend must be an o3d_spectral.correlation.Backend, got {backend!r}")
    return backend
