"""The phase-correlation peaks of many rotations of one cloud against one fixed grid.

:class:`BatchedCorrelation` holds the fixed grid's spectrum and the Gaussian window on
its backend (one transfer per correlation, none per rotation) and returns, for a stack of
rotations, each turned grid's peak height and where it lies
(:meth:`BatchedCorrelation.peaks`): the score by which the global search ranks rotations
(:func:`o3d_spectral.search.candidates.placed_peaks`).

The rotations are transformed in batches sized to the grid
(:meth:`o3d_spectral.correlation.backend.Backend.batch_size`), the batches shared out to
the workers in a few runs each (:data:`RUNS_PER_WORKER`), a run one call of the backend.
Each grid's peak is computed alone, whatever its batch or run: the same peaks to the bit
whatever the number of workers. Where a batch does not fit in memory the run is computed
again in batches half as large; a single grid that does not fit raises ``MemoryError``
naming the grid.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..common.parallel import resolved_workers, thread_map
from ..spectra.constants import WHITENING_EPS
from ..spectra.fft import next_fast_len
from ..spectra.translation import gaussian_window, peak_scale, peak_shifts
from .backend import Backend, Fixed, Found, array_backend
from .constants import RUNS_PER_WORKER
from .turned import TurnedCloud

__all__ = ["BatchedCorrelation", "Peaks"]


class Peaks(NamedTuple):
    """The phase-correlation peaks of a stack of rotations.

    Attributes
    ----------
    heights : ndarray, shape (B,)
        Peak heights in [0, 1] (1: the turned grid is the fixed one shifted).
    shifts : ndarray, shape (B, 3), int
        Where each peak lies: the shift, whole voxels, that moves each turned moving grid
        onto the fixed grid, both grids' corners at the origin (``fixed(x) ~
        moving(x - shift)``).
    fractions : ndarray, shape (B, 3)
        The sub-voxel part of each shift, in [-0.5, 0.5] voxels: the summit of the
        Gaussian through the peak and its neighbours along each axis
        (:func:`o3d_spectral.spectra.translation.subvoxel_offsets`); none along an axis
        where a neighbour lies outside the searched block.
    overlaps : ndarray, shape (B,)
        The unit-norm turned moving grid's inner product with the correlation's
        ``overlap`` grid before any shift (0 throughout where it has none).
    """

    heights: NDArray[np.float64]
    shifts: NDArray[np.int64]
    fractions: NDArray[np.float64]
    overlaps: NDArray[np.float64]


class BatchedCorrelation:
    """Phase correlation of turned copies of a cloud against one fixed grid, in batches.

    Parameters
    ----------
    fixed : array_like, shape (X, Y, Z)
        The fixed grid (non-negative), its corner at the origin of the shifts.
    moving_shape : tuple of 3 int
        The moving grid's shape (a cube holding the cloud under any rotation).
    shape : tuple of 3 int, optional
        The FFT grid, at least ``fixed.shape + moving_shape - 1`` per axis so that every
        shift is read unambiguously; the next fast lengths of the sums when omitted.
    sigma : float
        Width of the Gaussian window on the cross-power spectrum, voxels
        (:func:`o3d_spectral.spectra.translation.gaussian_window`).
    eps : float
        Cross-power terms under ``eps`` times the largest are not whitened
        (:func:`o3d_spectral.spectra.translation.cross_power_peak`).
    backend : Backend, optional
        The array library; NumPy on the CPU when omitted
        (:func:`o3d_spectral.correlation.backend.array_backend`).
    searched : tuple of 3 int, optional
        Seek the peak only at indices below these per axis, each read as a positive
        shift: for a fixed block filling the FFT grid, ``shape - moving_shape + 1``, the
        shifts that keep the moving grid inside it. Every shift of the padded grids when
        omitted.
    overlap : array_like, 3D, optional
        A grid each turned moving grid is compared with before any shift, over the cells
        they share (:attr:`Peaks.overlaps`): the fixed grid.
    overlap_at : array_like of 3 int, optional
        The moving grid's corner in ``overlap``, cells (any, negative too; the origin
        when omitted).
    spectrum : array_like, shape (nx, ny, nz // 2 + 1), optional
        The fixed grid's half spectrum on ``shape`` where it is already known (shared
        with other correlations against it); computed from ``fixed`` when omitted.

    Examples
    --------
    A cloud correlated with its own grid peaks at 1 for the identity, lower for a turn:

    >>> from o3d_spectral.correlation import BatchedCorrelation, TurnedCloud
    >>> from o3d_spectral.spectra.so3 import exp
    >>> points = np.random.default_rng(0).uniform(-6, 6, (300, 3))
    >>> cloud = TurnedCloud(points, offset=[8.0, 8.0, 8.0])
    >>> fixed = BatchedCorrelation.grid_of(cloud, (16, 16, 16))
    >>> correlation = BatchedCorrelation(fixed, (16, 16, 16))
    >>> peaks = correlation.peaks(cloud, np.stack([np.eye(3), exp([0.0, 0.0, 0.5])]))
    >>> bool(peaks.heights[0] > 0.99 and peaks.heights[1] < 0.9), peaks.shifts[0].tolist()
    (True, [0, 0, 0])
    """

    def __init__(
        self, fixed: ArrayLike, moving_shape: tuple[int, int, int], *,
        shape: tuple[int, int, int] | None = None, sigma: float = 1.0, eps: float = WHITENING_EPS,
        backend: Backend | None = None, searched: tuple[int, int, int] | None = None,
        overlap: ArrayLike | None = None, overlap_at: ArrayLike | None = None,
        spectrum: ArrayLike | None = None,
    ) -> None:
        fixed = np.asarray(fixed)  # only its shape is read where its spectrum is given
        if fixed.ndim != 3:
            raise ValueError(f"fixed must be a 3D grid, got shape {fixed.shape}")
        self.moving_shape = tuple(int(n) for n in moving_shape)
        if shape is None:
            shape = tuple(next_fast_len(a + b) for a, b in zip(fixed.shape, self.moving_shape,
                                                                strict=True))
        self.shape = tuple(int(n) for n in shape)
        self.searched = None if searched is None else tuple(int(n) for n in searched)
        if self.searched is not None:
            if not all(0 < s <= n for s, n in zip(self.searched, self.shape, strict=True)):
                raise ValueError(f"searched {self.searched} must lie within the FFT grid "
                                 f"{self.shape}, at least 1 per axis")
        elif any(n < a + b - 1 for n, a, b in zip(self.shape, fixed.shape, self.moving_shape,
                                                  strict=True)):
            raise ValueError(
                f"shape {self.shape} is too small for a fixed grid of {fixed.shape} and a "
                f"moving grid of {self.moving_shape}: shifts would wrap around"
            )
        self.fixed_shape = fixed.shape
        self.backend = array_backend(backend)
        self.scale = peak_scale(self.shape, sigma, np.float32)
        try:
            window = self.backend.asarray(gaussian_window(self.shape, sigma, np.float32),
                                          self.backend.xp.float32)
            compared = np.zeros((0, 0, 0)) if overlap is None else np.asarray(overlap,
                                                                                dtype=np.float64)
            if compared.ndim != 3:
                raise ValueError(f"overlap must be a 3D grid, got shape {compared.shape}")
            at = np.zeros(3, dtype=np.int64) if overlap_at is None else np.asarray(overlap_at)
            if at.shape != (3,) or not np.issubdtype(at.dtype, np.integer):
                raise ValueError(f"overlap_at must be 3 whole numbers of cells, got {overlap_at!r}")
            self.fixed = Fixed(self._spectrum(fixed, spectrum), window, float(eps),
                               self.moving_shape, self.shape, self.searched or self.shape,
                               self.backend.asarray(np.ascontiguousarray(compared),
                                                    self.backend.xp.float64),
                               at.astype(np.int64))
        except MemoryError as error:
            raise self._too_large() from error

    def _spectrum(self, fixed: NDArray, spectrum: ArrayLike | None) -> object:
        """The fixed grid's half spectrum on the backend: ``spectrum`` where given, of
        the FFT grid's half spectrum shape."""
        if spectrum is None:
            return self.backend.spectrum(fixed, self.shape)
        expected = (*self.shape[:2], self.shape[2] // 2 + 1)
        if np.shape(spectrum) != expected:
            raise ValueError(f"spectrum must be the half spectrum of the FFT grid {self.shape},"
                             f" shape {expected}, got {np.shape(spectrum)}")
        own = np.ascontiguousarray(spectrum, dtype=np.complex64)  # as the loop reads it
        return self.backend.asarray(own, self.backend.xp.complex64)

    @staticmethod
    def grid_of(
        cloud: TurnedCloud, shape: tuple[int, int, int],
        rotation: ArrayLike | None = None, backend: Backend | None = None,
    ) -> NDArray[np.float32]:
        """``cloud`` turned by ``rotation`` (3, 3; the identity when omitted) and splatted
        on a grid of ``shape``, as :meth:`peaks` splats it, on the host."""
        backend = array_backend(backend)
        R = np.eye(3) if rotation is None else np.asarray(rotation, dtype=np.float64)
        return backend.to_numpy(backend.splat(cloud, R[None], tuple(shape))[0])

    def peaks(
        self, cloud: TurnedCloud, rotations: ArrayLike, workers: int | None = 1
    ) -> Peaks:
        """The peak of the phase correlation of ``cloud`` turned by each of ``rotations``
        (B, 3, 3) against the fixed grid, the runs on ``workers`` threads where the
        backend runs them side by side (all cores when None).

        Returns
        -------
        Peaks
            Heights (B,), shifts (B, 3), their sub-voxel parts (B, 3) and overlaps (B,).
        """
        rotations = np.asarray(rotations, dtype=np.float64).reshape(-1, 3, 3)
        if not len(rotations):
            return Peaks(np.zeros(0), np.zeros((0, 3), dtype=np.int64), np.zeros((0, 3)),
                         np.zeros(0))
        batch = self.backend.batch_size(self.shape)
        workers = resolved_workers(workers) if self.backend.threaded else 1
        batches = -(-len(rotations) // batch)
        bounds = batch * np.linspace(0, batches, min(batches, RUNS_PER_WORKER * workers) + 1
                                     ).astype(int)
        runs = [rotations[a:b] for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
        found = thread_map(lambda run: self._run_peaks(cloud, run, batch), runs, workers)
        values, index, neighbours, overlaps = (np.concatenate(column) for column in
                                               zip(*found, strict=True))
        shifts, fractions = peak_shifts(index, values, neighbours, self.shape,
                                        positive_below=self.fixed_shape, searched=self.searched)
        return Peaks(values * self.scale, shifts, fractions, overlaps)

    def _run_peaks(
        self, cloud: TurnedCloud, rotations: NDArray[np.float64], batch: int
    ) -> Found:
        """The peaks of one run of rotations (:meth:`Backend.correlate`), in batches half
        as large where a batch does not fit in memory."""
        try:
            return self.backend.correlate(cloud, rotations, batch, self.fixed)
        except MemoryError as error:
            if batch == 1:
                raise self._too_large() from error
        return self._run_peaks(cloud, rotations, batch // 2)

    def _too_large(self) -> MemoryError:
        """The error of a single FFT grid that does not fit in memory."""
        shape = "x".join(str(n) for n in self.shape)
        return MemoryError(
            f"the batched phase correlation: one FFT grid of {shape} voxels does not fit "
            "in the memory left; use a larger voxel_size or crop the clouds"
        )
