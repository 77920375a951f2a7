"""Translation by 3D phase correlation (paper, eqs. fourier_coefs to fourier_shift_solution).

Given the spectra ``F = FFT3(f)`` and ``G = FFT3(g)`` of two grids of one shape, the
normalised cross-power spectrum ``C = G conj(F) / |G conj(F)|`` is a pure phase ramp when
``g`` is ``f`` shifted by ``s`` voxels, and ``IFFT3(C)`` is a Dirac peak at ``s``
(eq. cross_power_spectrum). Two additions make the peak usable for control:

- a Gaussian window on ``C`` turns the Dirac into a sampled Gaussian of width ``sigma``
  voxels (and damps the noisy high frequencies where voxelisation aliases), so that
- a Gaussian (log-parabola) fit through the peak and its neighbours along each axis gives
  the sub-voxel shift, exactly for a pure shift. The paper takes the integer argmax,
  which moves in whole voxels and chatters near convergence.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from .constants import WHITENING_EPS
from .fft import RealFFT3

__all__ = [
    "PeakEstimate", "gaussian_window", "peak_scale", "phase_correlation", "cross_power_peak",
    "peak_shifts", "subvoxel_offsets",
]


@dataclass(frozen=True)
class PeakEstimate:
    """Result of a phase correlation.

    Attributes
    ----------
    shift : ndarray, shape (3,)
        Shift of ``g`` relative to ``f`` in voxels (``g(x) ~ f(x - shift)``), signed, in
        ``[-n/2, n/2)`` per axis before the sub-voxel part.
    peak : float
        Height of the correlation peak in [0, 1]: 1 for a perfect shift (a little less
        when some frequencies are too weak to whiten), near 0 when the grids share no
        structure (a confidence figure).
    """

    shift: NDArray[np.float64]
    peak: float


@lru_cache(maxsize=8)
def gaussian_window(
    shape: tuple[int, int, int], sigma: float, dtype: type = np.float64
) -> NDArray[np.floating]:
    """Gaussian window on a half spectrum: ``exp(-2 pi^2 sigma^2 |nu|^2)``.

    Parameters
    ----------
    shape : tuple of 3 int
        Real-space grid shape.
    sigma : float
        Width of the resulting correlation peak, voxels (0: no window).
    dtype : numpy floating type
        Precision of the window (that of the spectra it multiplies).

    Returns
    -------
    ndarray, shape (nx, ny, nz // 2 + 1), read-only
        Frequencies ``nu`` in cycles per voxel.
    """
    nu = np.meshgrid(
        np.fft.fftfreq(shape[0]), np.fft.fftfreq(shape[1]), np.fft.rfftfreq(shape[2]),
        indexing="ij", sparse=True,
    )
    window = np.exp(-2.0 * np.pi**2 * sigma**2 * (nu[0] ** 2 + nu[1] ** 2 + nu[2] ** 2))
    window = window.astype(dtype)
    window.flags.writeable = False
    return window


@lru_cache(maxsize=8)
def peak_scale(shape: tuple[int, int, int], sigma: float, dtype: type = np.float64) -> float:
    """The factor that makes a windowed phase correlation's value a peak height in [0, 1]:
    the grid's size over the sum of :func:`gaussian_window` (of ``dtype``) over the full
    spectrum (both halves), the value a perfect match reaches being that sum over the
    size."""
    window = gaussian_window(shape, sigma, dtype)
    total = 2.0 * window.sum(dtype=np.float64) - window[..., 0].sum(dtype=np.float64)
    if shape[2] % 2 == 0:
        total -= window[..., -1].sum(dtype=np.float64)
    return float(np.prod(shape)) / float(total)


def _neighbours(values: NDArray[np.floating], index: tuple[int, ...]) -> NDArray[np.floating]:
    """The values one cell before and after ``index`` along each axis of ``values``
    (3D), wrapping around: shape (1, 3, 2), as :func:`peak_shifts` reads them."""
    around = np.empty((1, 3, 2), dtype=values.dtype)
    for axis in range(3):
        for side, step in enumerate((-1, 1)):
            i = list(index)
            i[axis] = (i[axis] + step) % values.shape[axis]
            around[0, axis, side] = values[tuple(i)]
    return around


def subvoxel_offsets(
    before: NDArray[np.floating], peak: NDArray[np.floating], after: NDArray[np.floating]
) -> NDArray[np.float64]:
    """Offsets in [-0.5, 0.5] of a sampled peak's summit from the sample ``peak``, given
    the samples ``before`` and ``after`` it along one axis (arrays of one shape): the
    vertex of the parabola through the three logarithms where all three are positive
    (exact for a sampled Gaussian, the windowed correlation's peak), through the values
    otherwise; 0 where they do not curve down. In the samples' precision."""
    lo, mid, hi = (np.asarray(v) for v in (before, peak, after))
    positive = (lo > 0) & (mid > 0) & (hi > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        lo, mid, hi = (np.where(positive, np.log(np.where(positive, v, v.dtype.type(1))), v)
                       for v in (lo, mid, hi))
        curvature = lo - 2.0 * mid + hi
        offsets = np.clip(0.5 * (lo - hi) / curvature, -0.5, 0.5)
    return np.where(curvature < 0, offsets, 0.0).astype(np.float64)


def peak_shifts(
    index: NDArray[np.int64], values: NDArray[np.floating], neighbours: NDArray[np.floating],
    shape: tuple[int, int, int], *, positive_below: tuple[int, int, int] | None = None,
    searched: tuple[int, int, int] | None = None,
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """The shifts (whole voxels, and their sub-voxel parts) that correlation peaks found
    at flat ``index`` in FFT grids of ``shape`` stand for, as :func:`cross_power_peak`
    reads them.

    Parameters
    ----------
    index : ndarray, shape (K,)
        Each peak's flat index.
    values : ndarray, shape (K,)
        Each peak's value; the sub-voxel fit runs in the neighbours' precision.
    neighbours : ndarray, shape (K, 3, 2)
        The correlation one voxel before and after each peak along each axis.
    shape : tuple of 3 int
        The FFT grid.
    positive_below, searched : tuple of 3 int, optional
        As for :func:`cross_power_peak`: indices at or beyond ``positive_below`` are
        negative shifts (half the grid when neither is given); within ``searched`` every
        index is a positive shift, and there is no fit along an axis where a neighbour
        lies outside it.

    Returns
    -------
    shifts : ndarray, shape (K, 3), int64
    fractions : ndarray, shape (K, 3)
        In [-0.5, 0.5] voxels (:func:`subvoxel_offsets`).
    """
    at = np.stack(np.unravel_index(np.asarray(index), shape), axis=-1).reshape(-1, 3)
    peak = np.asarray(values).astype(neighbours.dtype)
    fractions = np.stack([subvoxel_offsets(neighbours[:, a, 0], peak, neighbours[:, a, 1])
                          for a in range(3)], axis=-1).reshape(-1, 3)
    if searched is not None:
        fractions[(at == 0) | (at >= np.asarray(searched) - 1)] = 0.0
        return at.astype(np.int64), fractions
    size = np.asarray(shape)
    limit = (size + 1) // 2 if positive_below is None else np.asarray(positive_below)
    return np.where(at >= limit, at - size, at).astype(np.int64), fractions


def cross_power_peak(
    F: NDArray[np.complex128],
    G: NDArray[np.complex128],
    fft: RealFFT3,
    *,
    sigma: float = 1.0,
    eps: float = WHITENING_EPS,
    positive_below: tuple[int, int, int] | None = None,
    searched: tuple[int, int, int] | None = None,
) -> PeakEstimate:
    """Phase correlation of two half spectra (eqs. cross_power_spectrum, fourier_shift_solution).

    Parameters
    ----------
    F, G : ndarray, shape ``fft.spectrum_shape``
        Spectra of the moving grid ``f`` and the fixed grid ``g``.
    fft : RealFFT3
        Transform of the grids' shape.
    sigma : float
        Width of the Gaussian window, voxels.
    eps : float
        Cross-power terms smaller than ``eps`` times the largest are not whitened
        (they carry no phase information).
    positive_below : tuple of 3 int, optional
        Peak indices below this (per axis) are positive shifts, the others negative
        (``index - n``). Half the grid when omitted; pass the fixed grid's size when the
        two grids were zero-padded from their corners, so that shifts in
        ``[-(moving size - 1), fixed size - 1]`` are all read correctly.
    searched : tuple of 3 int, optional
        The peak is sought only at indices below this (per axis), each read as a
        positive shift; replaces ``positive_below``. For a moving grid zero-padded from
        the corner and a fixed block filling the FFT grid, ``FFT size - moving size + 1``:
        the shifts that keep the moving grid inside the block, the only ones that do not
        wrap around.

    Returns
    -------
    PeakEstimate
        The shift of ``g`` relative to ``f``, voxels.
    """
    cross = _whitened(F, G, fft.shape, sigma, eps)
    if searched is not None:  # only the searched block of the correlation is computed
        searched = tuple(int(b) for b in np.minimum(searched, fft.shape))
        delta = fft.inverse_cropped(cross, searched)
    else:
        delta = fft.inverse(cross)
    flat = int(np.argmax(delta))
    index = np.unravel_index(flat, delta.shape)
    shifts, fractions = peak_shifts(np.array([flat]), delta[index][None],
                                    _neighbours(delta, index), delta.shape,
                                    positive_below=positive_below, searched=searched)
    peak = float(_peak_height(delta[index], fft.shape, sigma))
    return PeakEstimate(shifts[0] + fractions[0], peak)


def _whitened(
    F: NDArray[np.complexfloating], G: NDArray[np.complexfloating],
    shape: tuple[int, int, int], sigma: float, eps: float,
) -> NDArray[np.complexfloating]:
    """The windowed, normalised cross-power spectrum ``window G conj(F) / |G conj(F)|``
    (eq. cross_power_spectrum) of one spectrum ``F`` or a stack of them (leading axis),
    terms under ``eps`` times each one's largest not whitened."""
    cross = np.conjugate(F)
    cross *= G
    magnitude = np.abs(cross)
    top = magnitude.max(axis=(-3, -2, -1), keepdims=True)
    np.maximum(magnitude, eps * top + 1e-300, out=magnitude)
    window = gaussian_window(shape, sigma, magnitude.dtype.type)
    cross *= np.divide(window, magnitude, out=magnitude)  # whitened and windowed in one pass
    return cross


def _peak_height(
    values: NDArray[np.floating], shape: tuple[int, int, int], sigma: float
) -> NDArray[np.float64]:
    """Correlation values as peak heights in [0, 1]: a perfect match's value is the
    window's sum over the full spectrum over the grid size."""
    return np.asarray(values, dtype=np.float64) * peak_scale(shape, sigma, values.dtype.type)


def phase_correlation(
    f: NDArray[np.float64], g: NDArray[np.float64], *, sigma: float = 1.0
) -> PeakEstimate:
    """Shift between two voxel grids of one shape by 3D phase correlation.

    A convenience wrapper around :func:`cross_power_peak` for one-off calls.

    Parameters
    ----------
    f, g : ndarray, shape (nx, ny, nz)
        Moving and fixed grids. Zero-pad them beforehand so that the shift does not wrap
        around (a shift is unambiguous only within half the grid).
    sigma : float
        Width of the Gaussian window, voxels.

    Returns
    -------
    PeakEstimate
        ``shift`` (voxels) such that ``g(x) ~ f(x - shift)``.

    Examples
    --------
    >>> f = np.zeros((16, 16, 16)); f[4, 5, 6] = 1.0
    >>> g = np.roll(f, (2, -3, 1), axis=(0, 1, 2))
    >>> np.round(phase_correlation(f, g).shift, 6)
    array([ 2., -3.,  1.])
    """
    if f.shape != g.shape or f.ndim != 3:
        raise ValueError(f"f and g must be 3D grids of one shape, got {f.shape} and {g.shape}")
    fft = RealFFT3(f.shape)
    F = np.array(fft.forward(f))
    return cross_power_peak(F, np.array(fft.forward(g)), fft, sigma=sigma)
