"""Planned 3D real FFTs: FFTW through pyfftw, or ``scipy.fft`` (pocketfft).

A :class:`RealFFT3` is built once per grid shape and reused on every iteration, one per
thread (:func:`fft_plan`). Single-threaded by default, the paper's setting.

Which library transforms a shape is fixed by the shape, so that a result never depends
on timing: FFTW's quickly planned (``FFTW_ESTIMATE``) transforms are fast when every
side is a power of two and often half as fast as pocketfft otherwise (one thread, single
precision, cubes: 32^3 0.06 against 0.11 ms, 128^3 10 against 16 ms; 30^3 0.24 against
0.10 ms, 90^3 7.5 against 3.1 ms); measured plans (``planning="measure"``) are FFTW's.

SciPy is imported where a transform runs, not with the module: the batched correlation
on a GPU (:mod:`o3d_spectral.correlation`) runs where only NumPy and CuPy are installed.
"""

from __future__ import annotations

import threading
from collections import OrderedDict

import numpy as np
from numpy.typing import NDArray

from .constants import CACHED_PLANS

try:  # pragma: no cover - exercised by whichever backend is installed
    import pyfftw
    import pyfftw.builders
except ImportError:  # pragma: no cover
    pyfftw = None

__all__ = [
    "RealFFT3", "fft_plan", "next_fast_len", "backend", "padded_forward", "cropped_inverse",
]


def backend(shape: tuple[int, ...], planning: str = "estimate") -> str:
    """Library transforming ``shape`` with ``planning``: ``"pyfftw"`` (installed, and a
    measured plan or every side a power of two) or ``"scipy"``."""
    powers_of_two = all(n > 0 and n & (n - 1) == 0 for n in shape)
    return "pyfftw" if pyfftw is not None and (planning == "measure" or powers_of_two) else "scipy"


def next_fast_len(n: int) -> int:
    """Smallest length ``>= n`` whose FFT is fast (factors 2, 3, 5, 7)."""
    import scipy.fft
    return int(scipy.fft.next_fast_len(int(n), real=True))


class RealFFT3:
    """Forward and inverse real 3D FFT of one fixed shape.

    Parameters
    ----------
    shape : tuple of 3 int
        Real-space grid shape ``(nx, ny, nz)``; the spectrum has shape
        ``(nx, ny, nz // 2 + 1)``.
    threads : int, optional
        Worker threads.
    planning : {"estimate", "measure"}
        FFTW planner effort: ``"measure"`` times candidate algorithms (a few hundred
        milliseconds per new shape, about 20% faster transforms afterwards: worth it for
        long servoing runs); ``"estimate"`` plans at once (right for one registration).
    precision : {"single", "double"}
        Floating-point precision of the grids and spectra; single is about twice as fast
        and ample for locating a correlation peak (relative error ~1e-7).

    Notes
    -----
    With FFTW (:func:`backend`), :meth:`forward` and :meth:`inverse` return views of
    internal buffers that the next call overwrites: copy a result you want to keep.
    """

    def __init__(
        self,
        shape: tuple[int, int, int],
        *,
        threads: int = 1,
        planning: str = "estimate",
        precision: str = "double",
    ) -> None:
        if planning not in ("estimate", "measure"):
            raise ValueError(f"planning must be 'estimate' or 'measure', got {planning!r}")
        if precision not in ("single", "double"):
            raise ValueError(f"precision must be 'single' or 'double', got {precision!r}")
        self.dtype = np.dtype(np.float32 if precision == "single" else np.float64)
        complex_dtype = np.complex64 if precision == "single" else np.complex128
        self.shape = tuple(int(n) for n in shape)
        self.spectrum_shape = (*self.shape[:2], self.shape[2] // 2 + 1)
        self.threads = threads
        self._fftw = backend(self.shape, planning) == "pyfftw"
        # pocketfft on one thread transforms only the lines a cropped result needs;
        # FFTW's plans, and several workers, take the grid whole
        self._pruned = not self._fftw and threads == 1
        if self._fftw:
            real = pyfftw.empty_aligned(self.shape, dtype=self.dtype)
            spec = pyfftw.empty_aligned(self.spectrum_shape, dtype=complex_dtype)
            kwargs = dict(threads=threads, planner_effort=f"FFTW_{planning.upper()}")
            self._forward = pyfftw.builders.rfftn(real, **kwargs)
            self._inverse = pyfftw.builders.irfftn(spec, s=self.shape, **kwargs)

    def forward(self, grid: NDArray[np.floating]) -> NDArray[np.complexfloating]:
        """Spectrum of a real grid of shape :attr:`shape`."""
        import scipy.fft
        if not self._fftw:
            return scipy.fft.rfftn(grid.astype(self.dtype, copy=False), workers=self.threads)
        return self._forward(grid)

    def inverse(self, spectrum: NDArray[np.complexfloating]) -> NDArray[np.floating]:
        """Real grid of shape :attr:`shape` from a half spectrum."""
        import scipy.fft
        if not self._fftw:
            return scipy.fft.irfftn(spectrum, s=self.shape, workers=self.threads)
        return self._inverse(spectrum)

    def inverse_cropped(
        self, spectrum: NDArray[np.complexfloating], size: tuple[int, int, int]
    ) -> NDArray[np.floating]:
        """The leading block of ``size`` of :meth:`inverse` (:func:`cropped_inverse`;
        FFTW transforms the grid whole)."""
        if not self._pruned:
            return self.inverse(spectrum)[: size[0], : size[1], : size[2]]
        return cropped_inverse(spectrum, self.shape, size)


def padded_forward(
    blocks: NDArray[np.floating], shape: tuple[int, int, int]
) -> NDArray[np.complexfloating]:
    """Half spectrum of a real block zero-padded from its corner to ``shape``, or of each
    of a stack of blocks (B, ...): ``rfftn`` of the padded grid, by pocketfft
    (``scipy.fft``) one axis at a time, transforming only the lines the block reaches
    (a block spanning 40% of each side: half the work of the whole grid's transform;
    equal to the whole grid's to rounding)."""
    import scipy.fft
    rows = scipy.fft.rfft(blocks, n=shape[2], axis=-1)
    out = scipy.fft.fft(rows, n=shape[1], axis=-2)
    return scipy.fft.fft(out, n=shape[0], axis=-3)


def cropped_inverse(
    spectrum: NDArray[np.complexfloating], shape: tuple[int, int, int],
    size: tuple[int, int, int],
) -> NDArray[np.floating]:
    """The leading block of ``size`` of the real grid of ``shape`` whose half spectrum is
    ``spectrum`` (``irfftn(spectrum)[:size[0], :size[1], :size[2]]``), by pocketfft one
    axis at a time, computing only the lines the block needs."""
    import scipy.fft
    out = scipy.fft.ifft(spectrum, axis=0)[: size[0]]
    out = scipy.fft.ifft(out, axis=1)[:, : size[1]]
    return scipy.fft.irfft(out, n=shape[2], axis=2)[:, :, : size[2]]


_plans = threading.local()  # each thread its own plans: a plan's buffers are overwritten
_planning = threading.Lock()  # by every call; and FFTW's planner is not thread-safe


def fft_plan(
    shape: tuple[int, int, int],
    threads: int = 1,
    planning: str = "estimate",
    precision: str = "double",
) -> RealFFT3:
    """Cached :class:`RealFFT3` for ``shape``, reused across calls in one thread.

    Each thread has its own plans: a plan returns views of its internal buffers, which
    the next call overwrites, so two threads must never share one.
    """
    cache = getattr(_plans, "cache", None)
    if cache is None:
        cache = _plans.cache = OrderedDict()
    key = (tuple(int(n) for n in shape), threads, planning, precision)
    plan = cache.get(key)
    if plan is None:
        with _planning:
            plan = RealFFT3(key[0], threads=threads, planning=planning, precision=precision)
        cache[key] = plan
        if len(cache) > CACHED_PLANS:
            cache.popitem(last=False)
    else:
        cache.move_to_end(key)
    return plan
