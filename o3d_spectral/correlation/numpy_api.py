"""The batched correlation's pipeline in plain array operations, on any library with
NumPy's API (NumPy, CuPy).

:class:`ArrayBackend` works on whole stacks at a time: the reference the compiled loops of
:class:`~o3d_spectral.correlation.backend.CompiledBackend` are tested against, and the
path a GPU library runs.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from types import ModuleType

import numpy as np
from numpy.typing import NDArray

from .backend import Array, Backend, Fixed, Found
from .constants import GPU_BYTES_PER_CELL, GPU_MEMORY_SHARE
from .turned import TurnedCloud

__all__ = ["ArrayBackend", "GPU_MEMORY_SHARE", "GPU_BYTES_PER_CELL"]


class ArrayBackend(Backend):
    """Any library with NumPy's API (``numpy``, ``cupy``), whole stacks at a time in
    plain array operations (see the module docstring).

    On a GPU library the work runs on GPU ``device``; batches are sized to a share of its
    free memory (:data:`GPU_MEMORY_SHARE`); its out-of-memory errors are raised as
    ``MemoryError``, which :class:`~o3d_spectral.correlation.batched.BatchedCorrelation`
    answers with smaller batches. The fixed spectrum stays on the device for the
    correlation's life, and CuPy keeps the FFT plans of each shape (its plan cache).

    Parameters
    ----------
    xp : module, default numpy
        The array library.
    device : int, optional
        The GPU's index, for a GPU library (CuPy).
    """

    def __init__(self, xp: ModuleType = np, device: int | None = None) -> None:
        self.xp, self.device = xp, device
        self.threaded = xp is np
        self._scatter_add = xp.add.at if xp is np else _gpu_scatter_add(xp)
        self._out_of_memory = _gpu_memory_errors(xp)  # none for NumPy: MemoryError itself

    @contextlib.contextmanager
    def _on_device(self) -> Iterator[None]:
        """The block on :attr:`device` (a GPU library), its out-of-memory errors raised
        as ``MemoryError``."""
        context = (contextlib.nullcontext() if self.device is None
                   else self.xp.cuda.Device(self.device))
        try:
            with context:
                yield
        except self._out_of_memory as error:
            raise MemoryError(f"out of GPU memory: {error}") from error

    def asarray(self, values: NDArray, dtype: type) -> Array:
        with self._on_device():
            return self.xp.asarray(values, dtype=dtype)

    def batch_size(self, shape: tuple[int, int, int]) -> int:
        """Rotations together: a share of the GPU's free memory, at about
        :data:`GPU_BYTES_PER_CELL` a cell of the FFT grid; on the CPU as
        :meth:`Backend.batch_size`."""
        if self.device is None:
            return super().batch_size(shape)
        with self._on_device():
            free, _ = self.xp.cuda.Device(self.device).mem_info
        return max(1, int(GPU_MEMORY_SHARE * free) // (GPU_BYTES_PER_CELL * int(np.prod(shape))))

    def splat(
        self, cloud: TurnedCloud, rotations: NDArray[np.float64], grid: tuple[int, int, int]
    ) -> Array:
        with self._on_device():
            return self._splat(cloud, rotations, grid)

    def _splat(
        self, cloud: TurnedCloud, rotations: NDArray[np.float64], grid: tuple[int, int, int]
    ) -> Array:
        xp = self.xp
        R = xp.asarray(rotations, dtype=xp.float64)
        u = xp.einsum("bij,mj->bmi", R, xp.asarray(cloud.points)) + xp.asarray(cloud.offset)
        facing = xp.ones(u.shape[:2], dtype=bool)
        if cloud.culled:
            normals = xp.einsum("bij,mj->bmi", R, xp.asarray(cloud.normals))
            cosine = xp.sum(normals * (xp.asarray(cloud.viewpoint) - u), axis=-1)
            facing = cosine != 0.0 if cloud.two_sided else cosine > 0.0
            facing[xp.sum(facing, axis=1) < cloud.min_facing] = True
        trilinear = cloud.weighting == "trilinear"
        start = xp.floor(u - 0.5) if trilinear else xp.floor(u)
        fraction = u - 0.5 - start
        cells = int(np.prod(grid))
        out = xp.zeros(len(rotations) * cells, dtype=xp.float32)
        batch = xp.arange(len(rotations))[:, None] * cells
        size = xp.asarray(grid)
        for corner in np.ndindex(2, 2, 2) if trilinear else [(0, 0, 0)]:
            index = start.astype(xp.int64) + xp.asarray(corner)
            inside = facing & xp.all((index >= 0) & (index < size), axis=-1)
            weight = xp.ones(u.shape[:2])
            if trilinear:
                for axis, c in enumerate(corner):
                    weight = weight * (fraction[..., axis] if c else 1.0 - fraction[..., axis])
            flat = batch + (index[..., 0] * grid[1] + index[..., 1]) * grid[2] + index[..., 2]
            self._scatter_add(out, flat[inside], weight[inside].astype(xp.float32))
        if cloud.weighting == "binary":
            out = (out > 0).astype(xp.float32)
        return out.reshape(len(rotations), *grid)

    def correlate(
        self, cloud: TurnedCloud, rotations: NDArray[np.float64], batch: int, fixed: Fixed
    ) -> Found:
        """:meth:`Backend.correlate` in plain array operations, a batch at a time: splat,
        forward transform, whiten, inverse transform, peaks."""
        found = [Found(np.zeros(0), np.zeros(0, dtype=np.int64),
                       np.zeros((0, 3, 2), dtype=np.float32), np.zeros(0))]
        for start in range(0, len(rotations), max(1, batch)):
            grids = self.splat(cloud, rotations[start : start + batch], fixed.moving_shape)
            overlaps = self.overlaps(grids, fixed.overlap, fixed.overlap_at)
            whitened = self.whiten(self.forward(grids, fixed.shape), fixed.spectrum,
                                   fixed.window, fixed.eps)
            found.append(Found(*self.peaks(self.inverse(whitened, fixed.shape),
                                           fixed.searched), overlaps))
        return Found(*(np.concatenate(column) for column in zip(*found, strict=True)))

    def forward(self, grids: Array, shape: tuple[int, int, int]) -> Array:
        with self._on_device():
            spectra = self.xp.fft.rfftn(grids, s=shape, axes=(-3, -2, -1))
            return spectra.astype(self.xp.complex64)

    def whiten(self, spectra: Array, fixed: Array, window: Array, eps: float) -> Array:
        """``window fixed conj(F) / |fixed conj(F)|`` for each spectrum ``F`` of
        ``spectra`` (eq. cross_power_spectrum), terms under ``eps`` times the largest
        (that of the zero frequency, for non-negative grids) not whitened."""
        xp = self.xp
        with self._on_device():
            cross = fixed * xp.conj(spectra)
            top = xp.abs(spectra[:, 0, 0, 0]) * xp.abs(fixed[0, 0, 0])
            floor = xp.maximum(eps * top, 1e-30)[:, None, None, None]
            return cross * (window / xp.maximum(xp.abs(cross), floor))

    def inverse(self, spectra: Array, shape: tuple[int, int, int]) -> Array:
        """Real grids (B, *shape) of half spectra (B, ...)."""
        with self._on_device():
            grids = self.xp.fft.irfftn(spectra, s=shape, axes=(-3, -2, -1))
            return grids.astype(self.xp.float32)

    def peaks(
        self, grids: Array, searched: tuple[int, int, int]
    ) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.float32]]:
        """Each grid's largest value at indices below ``searched`` (per axis), its flat
        index in the whole grid (the first of equals in C order) and its neighbours
        (:attr:`Found.neighbours`), on the host: (B,), (B,) and (B, 3, 2)."""
        xp = self.xp
        with self._on_device():
            shape = grids.shape[1:]
            block = grids[:, : searched[0], : searched[1], : searched[2]]
            at = xp.argmax(block.reshape(len(grids), -1), axis=1)
            at = xp.stack(xp.unravel_index(at, block.shape[1:]), axis=-1)
            batch = xp.arange(len(grids))
            values = grids[batch, at[:, 0], at[:, 1], at[:, 2]]
            neighbours = xp.empty((len(grids), 3, 2), dtype=xp.float32)
            for axis in range(3):
                for side, step in enumerate((-1, 1)):
                    beside = at.copy()
                    beside[:, axis] = (beside[:, axis] + step) % shape[axis]
                    inside = xp.all(beside < xp.asarray(searched), axis=1)
                    neighbours[:, axis, side] = xp.where(
                        inside, grids[batch, beside[:, 0], beside[:, 1], beside[:, 2]], 0.0)
            index = (at[:, 0] * shape[1] + at[:, 1]) * shape[2] + at[:, 2]
            return (self.to_numpy(values).astype(np.float64),
                    self.to_numpy(index).astype(np.int64), self.to_numpy(neighbours))

    def overlaps(self, grids: Array, overlap: Array, at: NDArray[np.int64]) -> NDArray[np.float64]:
        """``<g, overlap> / |g|`` of each grid ``g`` of ``grids`` over the cells it shares
        with ``overlap``, its corner at ``at`` there (0 for an empty grid; 0 throughout for
        an empty ``overlap``), on the host: (B,)."""
        xp = self.xp
        if not overlap.size:
            return np.zeros(len(grids))
        shape = np.asarray(grids.shape[1:])
        lo, hi = np.maximum(-at, 0), np.minimum(shape, np.asarray(overlap.shape) - at)
        with self._on_device():
            flat = grids.reshape(len(grids), -1).astype(xp.float64)
            norm = xp.sqrt(xp.sum(flat * flat, axis=1))
            inner = xp.zeros(len(grids))
            if np.all(hi > lo):
                mine = tuple(slice(a, b) for a, b in zip(lo, hi, strict=True))
                theirs = tuple(slice(a + c, b + c) for a, b, c in zip(lo, hi, at, strict=True))
                shared = grids[(slice(None), *mine)].reshape(len(grids), -1)
                inner = shared.astype(xp.float64) @ overlap[theirs].reshape(-1)
            return self.to_numpy(xp.where(norm > 0, inner / xp.where(norm > 0, norm, 1.0), 0.0))


def _gpu_scatter_add(xp: ModuleType):
    """``xp``'s unbuffered scatter-add (``np.add.at``'s): CuPy's ``cupyx.scatter_add``."""
    import importlib

    return importlib.import_module(f"{xp.__name__}x").scatter_add


def _gpu_memory_errors(xp: ModuleType) -> tuple[type[BaseException], ...]:
    """A GPU library's out-of-memory errors: CuPy's allocator's, and cuFFT's (a plan's
    work area it cannot allocate)."""
    cuda = getattr(xp, "cuda", None)
    found = [getattr(getattr(cuda, "memory", None), "OutOfMemoryError", None),
             getattr(getattr(cuda, "cufft", None), "CuFFTError", None)]
    return tuple(error for error in found if isinstance(error, type))
