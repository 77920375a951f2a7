"""The fixed cloud's voxel grid and the phase correlation of moving clouds against it.

:class:`TargetGrid` splats the fixed cloud once on a lattice anchored at the voxel size,
caches the spectra of the blocks it is correlated on, and turns a moving cloud's points
into the shift that takes them onto the fixed cloud (paper, eq. fourier_shift_solution),
the peak's height and the translation cost ``J_t``. Grids of the moving cloud are cubes
large enough to hold it under any rotation. Searched anywhere, the FFT size per axis is
the fixed grid's size plus the moving grid's (rounded up to a fast length), which keeps
every shift between the two unambiguous whatever the distance between the clouds; near a
prediction (the law's iterations), it is the size of a block of the fixed grid about it,
and only the shifts that keep the moving grid inside the block are read.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..io.cloud import extent
from ..io.rows import bounds
from .constants import CACHED_COARSE_GRIDS, CACHED_SPECTRA, SCENE_RATIO, WHITENING_EPS
from .correlation_loop import Splat, correlation_peaks
from .fft import fft_plan, next_fast_len
from .grid import Box, Lattice, check_memory, splat
from .translation import gaussian_window, peak_scale, peak_shifts

__all__ = ["Placement", "TargetGrid"]

#: Precision of the grids' FFTs: single halves their time, and the sub-voxel peak fit
#: does not need more.
PRECISION = "single"


@dataclass(frozen=True)
class Placement:
    """Where one phase correlation puts a moving cloud.

    Attributes
    ----------
    shift : ndarray, shape (3,)
        Shift (metres) taking the moving points onto the fixed cloud.
    peak : float
        Height of the phase-correlation peak in [0, 1] (1: identical grids).
    cost : float
        ``J_t = 1/2 ||g - f||^2`` of the unit-norm grids before the shift, in [0, 2].
    """

    shift: NDArray[np.float64]
    peak: float
    cost: float


class TargetGrid:
    """The fixed cloud's unit-norm voxel grid, its cached spectra, and phase correlation.

    Parameters
    ----------
    points : ndarray, shape (N, 3)
        The fixed cloud's down-sampled points, metres.
    voxel_size : float
        Voxel edge, metres.
    weighting : {"trilinear", "count", "binary"}
        How points fill the grid (:func:`o3d_spectral.spectra.grid.splat`).
    peak_width : float
        Width of the Gaussian window of the correlation, voxels.
    window : int or None
        Margin (voxels) of the block searched near an expected position (:meth:`search_box`).
    max_memory : float
        Largest memory (bytes) of one FFT grid.
    """

    def __init__(
        self, points: NDArray[np.float64], voxel_size: float, *, weighting: str,
        peak_width: float, window: int | None, max_memory: float,
    ) -> None:
        self.voxel_size = voxel_size
        self.weighting, self.peak_width = weighting, peak_width
        self.window, self.max_memory = window, max_memory
        lower, upper = bounds(points)
        self.lattice = Lattice(np.floor(lower / voxel_size) * voxel_size, voxel_size)
        self.box = self.lattice.box_around(lower, upper, margin=2)
        check_memory(self.box.shape, max_memory, "target")
        if not peak_width <= max(self.box.shape):  # the window would keep the mean alone
            raise ValueError(f"peak_width={peak_width:g} voxels is wider than the target's "
                             f"grid ({max(self.box.shape)} voxels across): the window would "
                             "blur the phase correlation's peak away")
        self._points = points
        self.radius = extent(points)[1]
        grid = splat(points, self.box, mode=weighting)
        self._grid = grid / np.linalg.norm(grid)
        self._spectra: dict[tuple, NDArray[np.complexfloating]] = {}
        self._coarsened: dict[float, TargetGrid] = {}
        self._lock = threading.Lock()  # the caches are shared by the threads using this grid

    @property
    def values(self) -> NDArray[np.float64]:
        """The fixed cloud's unit-norm grid on :attr:`box` (read only)."""
        view = self._grid.view()
        view.flags.writeable = False
        return view

    def coarsened(self, factor: float) -> TargetGrid:
        """The same fixed cloud on a grid of ``factor`` voxels, no window, built on first
        use and kept: many placements ranked at ``1 / factor^3`` of the FFT (placement
        ranking, :data:`COARSE_FACTOR`; the sweep of SO(3), :mod:`o3d_spectral.search.candidates`).
        ``self`` for a factor of 1."""
        if factor == 1.0:
            return self
        with self._lock:
            grid = self._coarsened.pop(factor, None) or TargetGrid(
                self._points, factor * self.voxel_size, weighting=self.weighting,
                peak_width=self.peak_width, window=None, max_memory=self.max_memory,
            )
            self._coarsened[factor] = grid  # the most recent last
            if len(self._coarsened) > CACHED_COARSE_GRIDS:
                del self._coarsened[next(iter(self._coarsened))]
            return grid

    def moving_box(self, radius: float, centre: NDArray[np.float64]) -> Box:
        """The cube holding a moving cloud of ``radius`` (metres) centred at ``centre``
        under any rotation."""
        side = next_fast_len(int(np.ceil(2.0 * radius / self.voxel_size)) + 4)
        half = side / 2.0 * self.voxel_size
        offset = np.floor((centre - half - self.lattice.origin) / self.voxel_size)
        return Box(self.lattice, offset.astype(np.int64), (side, side, side))

    def holds_more(self, radius: float) -> bool:
        """Whether the fixed cloud holds more than a moving cloud of ``radius`` (metres):
        its own radius over :data:`SCENE_RATIO` times that (a scene)."""
        return self.radius > SCENE_RATIO * radius

    def fft_shape(
        self, fixed: Box, moving: Box, radius: float | None = None
    ) -> tuple[int, int, int]:
        """The FFT grid on which ``moving`` (the grid of a moving cloud of ``radius``,
        metres) is correlated with ``fixed``: their sizes summed (every shift read
        unambiguously), except for a window about a prediction in a fixed cloud that holds
        no more than the moving one (:meth:`holds_more`): the block's own size (only the
        shifts keeping the moving grid in the block are read:
        :func:`o3d_spectral.spectra.translation.cross_power_peak`'s ``searched``). In a scene the
        block's content would wrap around its edges and change the peak heights that rank
        the climbs (cluttered suite: 136 successes of 240 against 145)."""
        if self._unpadded(fixed, radius):
            return tuple(next_fast_len(a) for a in fixed.shape)
        return tuple(next_fast_len(a + b) for a, b in zip(fixed.shape, moving.shape, strict=True))

    def _unpadded(self, fixed: Box, radius: float | None) -> bool:
        """Whether ``fixed`` is a window correlated on its own FFT size (:meth:`fft_shape`)."""
        return fixed is not self.box and radius is not None and not self.holds_more(radius)

    def searched(
        self, fixed: Box, moving: Box, radius: float
    ) -> tuple[int, int, int] | None:
        """The shifts read of the correlation of ``moving`` (the grid of a cloud of
        ``radius``, metres) with ``fixed`` on :meth:`fft_shape`: None for every shift, the
        peak's index below ``fixed.shape`` a positive shift and the others negative; for a
        window on its own FFT size, the block of indices, each a positive shift, that
        keep the moving grid inside the window (the only ones that do not wrap around)."""
        if not self._unpadded(fixed, radius):
            return None
        shape = self.fft_shape(fixed, moving, radius)
        return tuple(int(n) for n in np.subtract(shape, moving.shape) + 1)

    def search_box(self, radius: float, around: ArrayLike | None = None) -> Box:
        """The block of the fixed grid a moving cloud of ``radius`` is correlated with.

        The whole fixed grid when ``around`` or ``window`` is None (a global search).
        Otherwise a cube of the moving grid's side plus ``window`` voxels on each side,
        centred near ``around`` (metres, where the moving cloud's centroid is expected:
        snapped to a coarse step so that nearby predictions share one block and its cached
        spectrum). Outside a scene (:meth:`holds_more`) the cube grows to the next fast FFT
        length, which it fills, and is used when its FFT is smaller than the whole grid's;
        in a scene, padded (:meth:`fft_shape`), when its FFT is under half the whole's.
        """
        if around is None or self.window is None:
            return self.box
        moving = self.moving_box(radius, np.zeros(3))
        scene = self.holds_more(radius)
        side = moving.shape[0] + 2 * self.window
        if not scene:
            side = next_fast_len(side)  # the block fills its own FFT
        snap = max(self.window // 2, 1)
        centre = (np.asarray(around, dtype=np.float64) - self.lattice.origin) / self.voxel_size
        offset = (np.round(centre / snap) * snap).astype(np.int64) - side // 2
        window = Box(self.lattice, offset, (side, side, side))
        whole = np.prod(self.fft_shape(self.box, moving), dtype=np.float64)
        windowed = np.prod(self.fft_shape(window, moving, radius), dtype=np.float64)
        return window if windowed < (0.5 if scene else 1.0) * whole else self.box

    def correlate(
        self, moved: NDArray[np.float64], radius: float, centre: NDArray[np.float64],
        around: ArrayLike | None = None,
    ) -> Placement:
        """Voxelise ``moved`` (points of a moving cloud of ``radius``, centroid at
        ``centre``, metres) on the shared lattice and phase-correlate it with the fixed
        grid, near ``around`` when given (eq. fourier_shift_solution), on this thread's
        compiled loop (:func:`o3d_spectral.spectra.correlation_loop.correlation_peaks`,
        outside the GIL)."""
        box = self.moving_box(radius, centre)
        fixed = self.search_box(radius, around)
        shape = self.fft_shape(fixed, box, radius)
        searched = self.searched(fixed, box, radius)
        points = np.ascontiguousarray((moved - box.corner) / self.voxel_size)
        values, index, neighbours, overlaps = correlation_peaks(
            Splat.unculled(points, self.weighting), np.eye(3)[None],
            self.spectrum(fixed, box, radius), gaussian_window(shape, self.peak_width, np.float32),
            WHITENING_EPS, searched or shape, self._grid, box.offset - self.box.offset, batch=1,
            moving_shape=box.shape, shape=shape,
        )
        shifts, fractions = peak_shifts(index, values, neighbours, shape,
                                        positive_below=fixed.shape, searched=searched)
        shift = (fixed.offset - box.offset + shifts[0] + fractions[0]) * self.voxel_size
        peak = float(values[0]) * peak_scale(shape, self.peak_width, np.float32)
        return Placement(shift, peak, 1.0 - float(overlaps[0]))

    def block(self, box: Box) -> NDArray[np.float64]:
        """The unit-norm fixed grid on ``box`` (zero outside the fixed cloud's box; the
        grid itself, read only, for :attr:`box`)."""
        if box is self.box:
            return self.values
        out = np.zeros(box.shape)
        lo = np.maximum(box.offset, self.box.offset)
        hi = np.minimum(box.offset + box.shape, self.box.offset + self.box.shape)
        if np.all(hi > lo):
            a, b = lo - box.offset, hi - box.offset
            c, d = lo - self.box.offset, hi - self.box.offset
            out[a[0] : b[0], a[1] : b[1], a[2] : b[2]] = self._grid[
                c[0] : d[0], c[1] : d[1], c[2] : d[2]
            ]
        return out

    def spectrum(self, fixed: Box, moving: Box, radius: float) -> NDArray[np.complexfloating]:
        """The half spectrum of the block ``fixed`` on the FFT grid on which ``moving``
        (the grid of a cloud of ``radius``, metres) is correlated with it
        (:meth:`fft_shape`), single precision, read only: the one every correlation
        against that block shares (cached: a few blocks and shapes recur over a
        registration)."""
        shape = self.fft_shape(fixed, moving, radius)
        key = (tuple(fixed.offset), fixed.shape, shape)
        with self._lock:
            spectrum = self._spectra.get(key)
        if spectrum is None:
            check_memory(shape, self.max_memory, "voxel grids")
            fft = fft_plan(shape, precision=PRECISION)  # this thread's plan
            padded = np.zeros(shape, dtype=fft.dtype)
            f = fixed.shape
            padded[: f[0], : f[1], : f[2]] = self.block(fixed)
            spectrum = np.array(fft.forward(padded))
            spectrum.flags.writeable = False
            with self._lock:
                if len(self._spectra) >= CACHED_SPECTRA:
                    del self._spectra[next(iter(self._spectra))]
                self._spectra[key] = spectrum
        return spectrum
