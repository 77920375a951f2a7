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
* :class:`ArrayBackend`: any library with NumPy's API (NumPy, CuPy) over whole stacks in
  plain array operations: the reference the compiled loops are tested against, and the
  path a GPU library runs.

All grids are single precision, as the search's other phase correlations: it halves the
transforms' time, and the peak heights agree with
:meth:`o3d_spectral.SpectralStepper.locate`'s to about 1e-7 (``tests/test_ascent.py``
holds them to 1e-5).
"""

from __future__ import annotations

import contextlib
import threading
from abc import ABC, abstractmethod
from collections import OrderedDict
from collections.abc import Iterator
from types import ModuleType
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from .constants import BATCH_BYTES, GPU_BYTES_PER_CELL, GPU_MEMORY_SHARE, WORKSPACES
from .turned import TurnedCloud

__all__ = ["Backend", "CompiledBackend", "ArrayBackend", "Fixed", "array_backend", "BATCH_BYTES",
           "GPU_MEMORY_SHARE", "GPU_BYTES_PER_CELL"]


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
    """

    spectrum: Array
    window: Array
    eps: float
    moving_shape: tuple[int, int, int]
    shape: tuple[int, int, int]


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
    ) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        """The pipeline over ``rotations`` (K, 3, 3), ``batch`` grids at a time: each
        turned grid's correlation peak against ``fixed`` (unscaled) and its flat index in
        ``fixed.shape`` (the first of equals), on the host: (K,) and (K,). Each grid's
        peak is computed alone, whatever the batch; ``MemoryError`` where a batch does
        not fit."""


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
    ) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        from ..spectra.kernels import correlation_peaks_into

        values, index = np.empty(len(rotations)), np.empty(len(rotations), dtype=np.int64)
        correlation_peaks_into(values, index, cloud.points,
                               np.ascontiguousarray(rotations, dtype=np.float64), cloud.offset,
                               *_culling(cloud), fixed.spectrum, fixed.window,
                               np.float32(fixed.eps), *self._workspaces(batch, fixed))
        return values, index


def _culling(cloud: TurnedCloud) -> tuple:
    """The compiled splat's arguments after the offset: normals, viewpoint, culled,
    two_sided, min_facing, trilinear, binary (the points and offset stand in for the
    normals and viewpoint of a cloud that is not culled)."""
    normals = cloud.normals if cloud.culled else cloud.points
    viewpoint = cloud.viewpoint if cloud.culled else cloud.offset
    return (normals, viewpoint, cloud.culled, cloud.two_sided, cloud.min_facing,
            cloud.weighting == "trilinear", cloud.weighting == "binary")


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
    ) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        """:meth:`Backend.correlate` in plain array operations, a batch at a time: splat,
        forward transform, whiten, inverse transform, peaks."""
        values, index = [np.zeros(0)], [np.zeros(0, dtype=np.int64)]
        for start in range(0, len(rotations), max(1, batch)):
            grids = self.splat(cloud, rotations[start : start + batch], fixed.moving_shape)
            whitened = self.whiten(self.forward(grids, fixed.shape), fixed.spectrum,
                                   fixed.window, fixed.eps)
            found = self.peaks(self.inverse(whitened, fixed.shape))
            values.append(found[0])
            index.append(found[1])
        return np.concatenate(values), np.concatenate(index)

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

    def peaks(self, grids: Array) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        """Each grid's largest value and its flat index (the first of equals), on the
        host: (B,) and (B,)."""
        xp = self.xp
        with self._on_device():
            flat = grids.reshape(len(grids), -1)
            index = xp.argmax(flat, axis=1)
            values = xp.take_along_axis(flat, index[:, None], axis=1)[:, 0]
            return (self.to_numpy(values).astype(np.float64),
                    self.to_numpy(index).astype(np.int64))


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


def array_backend(backend: Backend | None = None) -> Backend:
    """``backend``, or the default: :class:`CompiledBackend` (NumPy on the CPU)."""
    if backend is None:
        return CompiledBackend()
    if not isinstance(backend, Backend):
        raise TypeError(f"backend must be an o3d_spectral.correlation.Backend, got {backend!r}")
    return backend
