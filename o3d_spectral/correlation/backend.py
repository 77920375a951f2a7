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

All grids are single precision, as the law's phase correlations (which run the same
compiled loop for one grid): it halves the transforms' time, and the peak heights agree
with the paper's steps in double precision to 1e-5 (``tests/test_target_grid.py``).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from types import ModuleType
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from ..spectra.correlation_loop import correlation_peaks
from .constants import BATCH_BYTES
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
    overlap : array, 3D or shape (0, 0, 0), float64
        A fixed grid each turned moving grid is compared with before any shift, over the
        cells they share (:attr:`Found.overlaps`); empty: not compared.
    overlap_at : ndarray, shape (3,), int64
        The moving grid's corner in :attr:`overlap`, cells.
    """

    spectrum: Array
    window: Array
    eps: float
    moving_shape: tuple[int, int, int]
    shape: tuple[int, int, int]
    searched: tuple[int, int, int]
    overlap: Array
    overlap_at: NDArray[np.int64]


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
        around the FFT grid (0 outside :attr:`Fixed.searched`).
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
    """NumPy on the CPU: the whole pipeline as one compiled loop over a run of batches on
    the calling thread, outside the GIL, on the workspaces the thread keeps
    (:func:`o3d_spectral.spectra.correlation_loop.correlation_peaks`; see the module
    docstring)."""

    xp = np
    threaded = True

    def splat(
        self, cloud: TurnedCloud, rotations: NDArray[np.float64], grid: tuple[int, int, int]
    ) -> NDArray[np.float32]:
        from ..spectra.kernels import turned_splat_into

        grids = np.zeros((len(rotations), *grid), dtype=np.float32)
        points, *rest = cloud.splat
        turned_splat_into(grids, points, np.ascontiguousarray(rotations, dtype=np.float64),
                          *rest)
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
        found = correlation_peaks(
            cloud.splat, rotations, fixed.spectrum, fixed.window, fixed.eps, fixed.searched,
            fixed.overlap, fixed.overlap_at, batch=batch, moving_shape=fixed.moving_shape,
            shape=fixed.shape,
        )
        return Found(*found)


def array_backend(backend: Backend | None = None) -> Backend:
    """``backend``, or the default: :class:`CompiledBackend` (NumPy on the CPU)."""
    if backend is None:
        return CompiledBackend()
    if not isinstance(backend, Backend):
        raise TypeError(f"backend must be an o3d_spectral.correlation.Backend, got {backend!r}")
    return backend
