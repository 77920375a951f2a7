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
from ..spectra.fft import next_fast_len
from ..spectra.translation import gaussian_window, peak_scale
from .backend import Backend, Fixed, array_backend
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
    """

    heights: NDArray[np.float64]
    shifts: NDArray[np.int64]


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
        shape: tuple[int, int, int] | None = None, sigma: float = 1.0, eps: float = 1e-6,
        backend: Backend | None = None,
    ) -> None:
        fixed = np.asarray(fixed, dtype=np.float32)
        if fixed.ndim != 3:
            raise ValueError(f"fixed must be a 3D grid, got shape {fixed.shape}")
        self.moving_shape = tuple(int(n) for n in moving_shape)
        if shape is None:
            shape = tuple(next_fast_len(a + b) for a, b in zip(fixed.shape, self.moving_shape,
                                                                strict=True))
        self.shape = tuple(int(n) for n in shape)
        if any(n < a + b - 1 for n, a, b in zip(self.shape, fixed.shape, self.moving_shape,
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
            self.fixed = Fixed(self.backend.spectrum(fixed, self.shape), window, float(eps),
                               self.moving_shape, self.shape)
        except MemoryError as error:
            raise self._too_large() from error

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
            Heights (B,) and shifts (B, 3).
        """
        rotations = np.asarray(rotations, dtype=np.float64).reshape(-1, 3, 3)
        batch = self.backend.batch_size(self.shape)
        workers = resolved_workers(workers) if self.backend.threaded else 1
        batches = -(-len(rotations) // batch)
        bounds = batch * np.linspace(0, batches, min(batches, RUNS_PER_WORKER * workers) + 1
                                     ).astype(int)
        runs = [rotations[a:b] for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
        found = thread_map(lambda run: self._run_peaks(cloud, run, batch), runs, workers)
        values = np.concatenate([np.zeros(0), *(v for v, _ in found)])
        index = np.concatenate([np.zeros(0, dtype=np.int64), *(i for _, i in found)])
        at = np.stack(np.unravel_index(index, self.shape), axis=-1).reshape(-1, 3)
        shifts = np.where(at >= np.asarray(self.fixed_shape), at - np.asarray(self.shape), at)
        return Peaks(values * self.scale, shifts.astype(np.int64))

    def _run_peaks(
        self, cloud: TurnedCloud, rotations: NDArray[np.float64], batch: int
    ) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
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
