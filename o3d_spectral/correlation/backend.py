"""What the batched phase correlation asks of an array library, and two answers.

:class:`~o3d_spectral.correlation.batched.BatchedCorrelation` runs one pipeline over a
stack of rotations: splat the turned cloud on the moving grid, transform it (zero-padded
to the FFT shape), whiten its cross-power against the fixed spectrum, transform back,
read each grid's peak. A :class:`Backend` supplies those five steps on its arrays:

* :class:`CompiledBackend`: NumPy on the CPU. Compiled loops (numba) turn, cull and
  splat the points and whiten the spectra in one pass each; pocketfft (``scipy.fft``)
  transforms in place in a workspace of each thread's, skipping the lines the zero
  padding leaves empty; the work is done outside the GIL, so that batches on threads use
  every core. Batches fill about a core's cache (:data:`BATCH_BYTES`): at the voxel's
  grid of a 0.2 m scan, one grid.
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

import numpy as np
from numpy.typing import NDArray

from .constants import BATCH_BYTES, GPU_BYTES_PER_CELL, GPU_MEMORY_SHARE, WORKSPACES
from .turned import TurnedCloud

__all__ = ["Backend", "CompiledBackend", "ArrayBackend", "array_backend", "BATCH_BYTES",
           "GPU_MEMORY_SHARE", "GPU_BYTES_PER_CELL"]


Array = object  # an array of the backend's library


class Backend(ABC):
    """The five steps of the batched correlation on one array library.

    Attributes
    ----------
    xp : module
        The array library (``numpy``, ``cupy``).
    threaded : bool
        Whether batches run side by side on threads (a CPU library that releases the
        GIL) rather than one after the other (a GPU, which works on a whole batch).
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
        """The half spectrum of one grid zero-padded to ``shape``, on the backend, kept by
        the caller (:meth:`forward`'s may be a workspace)."""
        return self.forward(self.asarray(grid[None], self.xp.float32), shape)[0].copy()

    @abstractmethod
    def forward(self, grids: Array, shape: tuple[int, int, int]) -> Array:
        """Half spectra (B, nx, ny, nz // 2 + 1) of ``grids`` (B, ...) zero-padded from
        their corner to ``shape``; may be a workspace that the thread's next batch
        overwrites."""

    @abstractmethod
    def whiten(self, spectra: Array, fixed: Array, window: Array, eps: float) -> Array:
        """``window fixed conj(F) / |fixed conj(F)|`` for each spectrum ``F`` of
        ``spectra`` (eq. cross_power_spectrum), terms under ``eps`` times the largest
        (that of the zero frequency, for non-negative grids) not whitened; may overwrite
        ``spectra``."""

    @abstractmethod
    def inverse(self, spectra: Array, shape: tuple[int, int, int]) -> Array:
        """Real grids (B, *shape) of half spectra (B, ...)."""

    @abstractmethod
    def peaks(self, grids: Array) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        """Each grid's largest value and its flat index (the first of equals), on the
        host: (B,) and (B,)."""


class CompiledBackend(Backend):
    """NumPy on the CPU: compiled loops and pocketfft over a batch on the calling thread
    (see the module docstring).

    Each thread keeps its batch's spectra in a workspace of its own, transformed,
    whitened and transformed back in place: a batch allocates only the first transform's
    small output and the correlations. Fresh large arrays for every batch would have the
    memory allocator return them to the system and fault them in again, batch after
    batch, which costs a fifth of the time on one thread and serialises two (dragon scans
    at 3 voxels, 32x36x36 grids: 1.03x on two threads, 1.8x without the churn).
    """

    xp = np
    threaded = True

    def __init__(self) -> None:
        self._local = threading.local()

    def __getstate__(self) -> dict:
        return {}  # the workspaces stay with their threads (a copy starts without)

    def __setstate__(self, state: dict) -> None:
        self.__init__()

    def _workspace(self, shape: tuple[int, ...], dtype: type) -> NDArray:
        """This thread's array of ``shape`` and ``dtype``, kept for its next batches (the
        last few shapes)."""
        kept = getattr(self._local, "arrays", None)
        if kept is None:
            kept = self._local.arrays = OrderedDict()
        key = (shape, np.dtype(dtype).str)
        array = kept.pop(key, None)
        if array is None:
            array = np.empty(shape, dtype=dtype)
        kept[key] = array
        if len(kept) > WORKSPACES:
            kept.popitem(last=False)
        return array

    def splat(
        self, cloud: TurnedCloud, rotations: NDArray[np.float64], grid: tuple[int, int, int]
    ) -> NDArray[np.float32]:
        from ..spectra.kernels import turned_splat_into

        grids = self._workspace((len(rotations), *grid), np.float32)
        grids.fill(0.0)
        normals = cloud.normals if cloud.culled else cloud.points
        viewpoint = cloud.viewpoint if cloud.culled else cloud.offset
        turned_splat_into(grids, cloud.points, np.ascontiguousarray(rotations, dtype=np.float64),
                          cloud.offset, normals, viewpoint, cloud.culled, cloud.two_sided,
                          cloud.min_facing, cloud.weighting == "trilinear",
                          cloud.weighting == "binary")
        return grids

    def forward(
        self, grids: NDArray[np.float32], shape: tuple[int, int, int]
    ) -> NDArray[np.complex64]:
        """:meth:`Backend.forward` into this thread's workspace (overwritten by its next
        batch), transforming only the lines the grids reach, one axis at a time
        (:func:`o3d_spectral.spectra.fft.padded_forward`, in place)."""
        from ..spectra.fft import padded_forward

        spectra = self._workspace((len(grids), shape[0], shape[1], shape[2] // 2 + 1),
                                  np.complex64)
        return padded_forward(grids, shape, out=spectra)

    def whiten(
        self, spectra: NDArray[np.complex64], fixed: NDArray[np.complex64],
        window: NDArray[np.float32], eps: float,
    ) -> NDArray[np.complex64]:
        from ..spectra.kernels import whitened_into

        reals = spectra.view(np.float32)
        whitened_into(reals, fixed.view(np.float32), window, np.float32(eps), reals)
        return spectra

    def inverse(
        self, spectra: NDArray[np.complex64], shape: tuple[int, int, int]
    ) -> NDArray[np.float32]:
        """:meth:`Backend.inverse`, overwriting ``spectra``."""
        import scipy.fft

        scipy.fft.ifftn(spectra, axes=(-3, -2), overwrite_x=True)
        return scipy.fft.irfft(spectra, n=shape[2], axis=-1)

    def peaks(self, grids: NDArray[np.float32]) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        flat = grids.reshape(len(grids), -1)
        index = np.argmax(flat, axis=1)
        return np.take_along_axis(flat, index[:, None], axis=1)[:, 0].astype(np.float64), index


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

    def forward(self, grids: Array, shape: tuple[int, int, int]) -> Array:
        with self._on_device():
            spectra = self.xp.fft.rfftn(grids, s=shape, axes=(-3, -2, -1))
            return spectra.astype(self.xp.complex64)

    def whiten(self, spectra: Array, fixed: Array, window: Array, eps: float) -> Array:
        xp = self.xp
        with self._on_device():
            cross = fixed * xp.conj(spectra)
            top = xp.abs(spectra[:, 0, 0, 0]) * xp.abs(fixed[0, 0, 0])
            floor = xp.maximum(eps * top, 1e-30)[:, None, None, None]
            return cross * (window / xp.maximum(xp.abs(cross), floor))

    def inverse(self, spectra: Array, shape: tuple[int, int, int]) -> Array:
        with self._on_device():
            grids = self.xp.fft.irfftn(spectra, s=shape, axes=(-3, -2, -1))
            return grids.astype(self.xp.float32)

    def peaks(self, grids: Array) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
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
