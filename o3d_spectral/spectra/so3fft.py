"""The rotation correlation over all of SO(3) at once, by an SO(3) Fourier transform.

``C_r(R) = 1/(4 pi) sum_l G^T U(R) F`` (paper, eq. correlation_rotation) on a grid of ZYZ
Euler angles ``R = Rz(alpha) Ry(beta) Rz(gamma)``. With ``U(R) = Uz(alpha) d(beta)
Uz(gamma)`` and ``W`` the unitary change of basis in which rotations about z are diagonal
(``Uz(a) = W^H diag(exp(i m a)) W``)::

    C_r(alpha, beta, gamma) = 1/(4 pi) sum_{m,n} K_mn(beta) exp(i (m alpha + n gamma)),
    K_mn(beta) = sum_l conj(g^l_m) Delta^l_mn(beta) f^l_n,   g = W G, f = W F,
    Delta^l(beta) = W d^l(beta) W^H

so one 2D inverse FFT over ``(alpha, gamma)`` per ``beta`` gives the whole grid
(Kostelec & Rockmore, "FFTs on the rotation group", J. Fourier Anal. Appl. 14, 2008:
their SOFT does the same with complex Wigner-d). Zero-padding the FFT refines the
``alpha, gamma`` step below ``360 / (2B - 1)`` degrees; more ``beta`` samples refine
``beta``.

Against a single view, :func:`visible_correlation_grid` correlates what the sensor would
see of the turned moving EGI instead, normalised over that visible part: three such
transforms.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.fft
from numpy.typing import ArrayLike, NDArray
from scipy.ndimage import maximum_filter

from . import so3
from .egi import grid_points
from .harmonics import isht, resize, sht
from .wigner import quarter_turn, wigner_z

__all__ = ["CorrelationGrid", "correlation_grid", "visible_correlation_grid", "peaks",
           "peak_indices"]


@dataclass(frozen=True)
class CorrelationGrid:
    """``C_r`` sampled on a ZYZ Euler-angle grid.

    Attributes
    ----------
    values : ndarray, shape (n_beta, n_alpha, n_alpha)
        ``[j, a, c] = C_r(alphas[a], betas[j], gammas[c])``.
    alphas, gammas : ndarray, shape (n_alpha,)
        ``2 pi k / n_alpha``, radians.
    betas : ndarray, shape (n_beta,)
        ``pi (j + 1/2) / n_beta``, radians.
    """

    values: NDArray[np.float64]
    alphas: NDArray[np.float64]
    betas: NDArray[np.float64]
    gammas: NDArray[np.float64]

    def rotation(self, index: tuple[int, int, int]) -> NDArray[np.float64]:
        """Rotation matrix (3, 3) at grid index ``(j, a, c)``."""
        j, a, c = index
        return so3.from_euler_zyz(self.alphas[a], self.betas[j], self.gammas[c])


@lru_cache(maxsize=8)
def diagonalising_basis(bandwidth: int) -> NDArray[np.complex128]:
    """``W`` (2B-1, 2B-1): rows ``m > 0``: ``(e_m + i e_-m) / sqrt2``; ``m < 0``:
    ``(e_|m| - i e_-|m|) / sqrt2``; ``m = 0``: ``e_0``; ``W Uz(a) W^H = diag(exp(i m a))``."""
    B = bandwidth
    W = np.zeros((2 * B - 1, 2 * B - 1), dtype=np.complex128)
    W[B - 1, B - 1] = 1.0
    r = 1.0 / np.sqrt(2.0)
    for m in range(1, B):
        W[B - 1 + m, B - 1 + m], W[B - 1 + m, B - 1 - m] = r, 1j * r
        W[B - 1 - m, B - 1 + m], W[B - 1 - m, B - 1 - m] = r, -1j * r
    return W


@lru_cache(maxsize=8)
def _delta(bandwidth: int, n_beta: int) -> NDArray[np.complex128]:
    """``Delta^l(beta_j) = W Q Uz(beta_j) Q^T W^H``, shape (n_beta, B, 2B-1, 2B-1)."""
    Q = quarter_turn(bandwidth)
    betas = np.pi * (np.arange(n_beta) + 0.5) / n_beta
    d = np.stack([Q @ wigner_z(beta, bandwidth) @ Q.transpose(0, 2, 1) for beta in betas])
    out = change_basis(d)
    out.flags.writeable = False
    return out


def change_basis(d: NDArray[np.float64]) -> NDArray[np.complex128]:
    """``W d W^H`` for real stacked ``d`` (..., 2B-1, 2B-1), ``W`` of
    :func:`diagonalising_basis`.

    Row ``m`` of ``W`` mixes only orders ``m`` and ``-m``, so each side is a few real
    slices (no dense complex product: at a large bandwidth those products were most of
    the first global search of a process)."""
    h = d.shape[-1] // 2  # order m at index h + m
    r = 1.0 / np.sqrt(2.0)
    up, down = slice(h + 1, None), slice(0, h)  # m = 1..h; m = -h..-1
    up_mirror = slice(h - 1, None, -1) if h else slice(0, 0)  # -m for m = 1..h
    down_mirror = slice(2 * h, h, -1)  # -m for m = -h..-1
    # X = W d = Xr + i Xi (rows)
    Xr, Xi = np.empty_like(d), np.empty_like(d)
    Xr[..., h, :], Xi[..., h, :] = d[..., h, :], 0.0
    Xr[..., up, :], Xi[..., up, :] = r * d[..., up, :], r * d[..., up_mirror, :]
    Xr[..., down, :], Xi[..., down, :] = r * d[..., down_mirror, :], -r * d[..., down, :]
    # X W^H (columns)
    out = np.empty(d.shape, dtype=np.complex128)
    out.real[..., h], out.imag[..., h] = Xr[..., h], Xi[..., h]
    out.real[..., up] = r * (Xr[..., up] + Xi[..., up_mirror])
    out.imag[..., up] = r * (Xi[..., up] - Xr[..., up_mirror])
    out.real[..., down] = r * (Xr[..., down_mirror] - Xi[..., down])
    out.imag[..., down] = r * (Xi[..., down_mirror] + Xr[..., down])
    return out


def correlation_grid(
    F: ArrayLike, G: ArrayLike, *, n_alpha: int | None = None, n_beta: int | None = None
) -> CorrelationGrid:
    """``C_r`` (eq. correlation_rotation) on a whole grid of ZYZ Euler angles.

    Parameters
    ----------
    F, G : array_like, shape (B, 2B - 1) or (S, B, 2B - 1)
        Coefficients of the moving and the fixed EGI; or stacks of ``S`` functions each
        (the spectra's shells, :mod:`o3d_spectral.spectra.shells`), whose ``S`` correlations of
        ``F[s]`` with ``G[s]`` are summed.
    n_alpha : int, optional
        Samples of ``alpha`` and ``gamma`` (>= 2B - 1); ``2B`` when omitted.
    n_beta : int, optional
        Samples of ``beta``; ``2B`` when omitted.

    Returns
    -------
    CorrelationGrid
    """
    F, G = np.asarray(F, dtype=np.float64), np.asarray(G, dtype=np.float64)
    if F.shape != G.shape or F.ndim not in (2, 3):
        raise ValueError(f"F and G must both be (B, 2B - 1) or (S, B, 2B - 1), got "
                         f"{F.shape} and {G.shape}")
    F, G = F.reshape((-1,) + F.shape[-2:]), G.reshape((-1,) + G.shape[-2:])
    B = F.shape[1]
    n_alpha = 2 * B if n_alpha is None else int(n_alpha)
    n_beta = 2 * B if n_beta is None else int(n_beta)
    if n_alpha < 2 * B - 1:
        raise ValueError(f"n_alpha must be >= 2B - 1 = {2 * B - 1}, got {n_alpha}")
    if n_beta < 1:
        raise ValueError(f"n_beta must be positive, got {n_beta}")
    W = diagonalising_basis(B)
    g, f = G @ W.T, F @ W.T  # (S, B, 2B-1): g^l = W G^l
    products = np.einsum("slm,sln->lmn", g.conj(), f)  # summed over the stack
    K = np.einsum("jlmn,lmn->jmn", _delta(B, n_beta), products)  # (n_beta, m, n)
    values = _real_fourier_sum(K, n_alpha) / (4.0 * np.pi)
    angles = 2.0 * np.pi * np.arange(n_alpha) / n_alpha
    return CorrelationGrid(values, angles, np.pi * (np.arange(n_beta) + 0.5) / n_beta, angles)


def _real_fourier_sum(K: NDArray[np.complex128], n: int) -> NDArray[np.float64]:
    """``Re sum_mn K[j, m, n] exp(i (m a + n c))`` at ``a, c = 2 pi k / n`` (``k < n``),
    orders ``-(B - 1) .. B - 1`` of ``K`` (J, 2B - 1, 2B - 1) on its last two axes:
    shape (J, n, n).

    The terms of ``(m, n)`` and ``(-m, -n)`` are summed first (their real parts add up
    to that of ``(K_mn + conj K_-m-n) exp(i (m a + n c))``), so that only orders ``n >= 0``
    remain: an inverse FFT over ``m`` of those ``B`` columns and a real inverse FFT over
    ``n``, about a third of the work of the complex 2D transform of the whole grid, and
    equal to it to rounding."""
    B = (K.shape[-1] + 1) // 2
    half = K[..., B - 1 :].copy()  # n = 0 .. B - 1
    half[..., 1:] += np.conj(K[:, ::-1, B - 2 :: -1])  # + conj K[-m, -n] for n >= 1
    half[..., 1:] /= 2.0  # irfft counts each n >= 1 twice
    columns = np.zeros((K.shape[0], n, B), dtype=np.complex128)
    columns[:, np.arange(-(B - 1), B) % n, :] = half
    columns = scipy.fft.ifft(columns, axis=1, overwrite_x=True)
    spectrum = np.zeros((K.shape[0], n, n // 2 + 1), dtype=np.complex128)
    spectrum[..., :B] = columns
    return scipy.fft.irfft(spectrum, n=n, axis=2, overwrite_x=True) * float(n) ** 2


def visible_correlation_grid(
    F: ArrayLike,
    G: ArrayLike,
    weight: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    *,
    n_alpha: int | None = None,
    n_beta: int | None = None,
) -> CorrelationGrid:
    """The rotation correlation of a single view: ``g`` against ``w f_R``, normalised.

    A sensor samples a surface in proportion to a weight ``w(n) >= 0`` of its normal (a
    depth camera in direction ``d``: the cosine of incidence ``max(0, n . d)``,
    :func:`o3d_spectral.spectra.egi.facing`), so the fixed EGI ``g`` of one view is expected to
    be ``w f_R`` (``f_R(n) = f(R^T n)``: the moving EGI turned by ``R``), not ``f_R``.
    The grid holds the cosine similarity of the two, both without degree 0, over
    ``4 pi`` (the unit of :func:`correlation_grid` for unit-norm coefficients)::

        C_v(R) = int g' w f_R / (4 pi ||g'|| ||(w f_R)'||),
        ||(w f_R)'||^2 = int w^2 f_R^2 - (int w f_R)^2 / (4 pi)

    (``'``: degree 0 removed). Each integral is a rotation correlation of two known
    expansions (``g' w`` with ``f``, ``w^2`` with ``f^2``, ``w`` with ``f``), so three
    SO(3) transforms give the whole grid; the products are formed on the grid of
    bandwidth ``2B``, where ``f^2`` is exact. Normalising by the visible part is what
    keeps a rotation that turns the moving cloud's largest faces towards the sensor from
    winning whatever the view holds. ``C_v`` is the correlation the local law climbs
    against a single view (the moving cloud culled and weighted by the cosine of
    incidence at each pose, :meth:`o3d_spectral.SpectralStepper.evaluate`), up to the
    truncation of ``w f_R`` to degrees below ``B`` and the sensor's perspective.

    Parameters
    ----------
    F, G : array_like, shape (B, 2B - 1)
        Coefficients of the moving and the fixed EGI; ``F`` with its degree 0 (the
        mass), any scale.
    weight : callable
        ``w``: unit vectors (..., 3) to non-negative weights (...).
    n_alpha, n_beta : int, optional
        As for :func:`correlation_grid`.

    Returns
    -------
    CorrelationGrid
        ``values`` in ``[-1/4pi, 1/4pi]``; 0 where nothing of the moving EGI is seen.
    """
    F, G = np.asarray(F, dtype=np.float64), np.array(G, dtype=np.float64)
    B, fine = F.shape[0], 2 * F.shape[0]
    G[0] = 0.0
    w = np.asarray(weight(grid_points(fine)), dtype=np.float64)
    f, g = isht(resize(F, fine)), isht(resize(G, fine))

    def correlate(moving: NDArray[np.float64], fixed_samples: NDArray[np.float64]):
        fixed = resize(sht(fixed_samples, fine), B)
        return correlation_grid(moving, fixed, n_alpha=n_alpha, n_beta=n_beta)

    cross = correlate(F, g * w)  # int g' w f_R / 4 pi
    energy = correlate(resize(sht(f * f, fine), B), w * w).values  # int w^2 f_R^2 / 4 pi
    mean = correlate(F, w).values  # int w f_R / 4 pi
    variance = 4.0 * np.pi * (energy - mean**2)  # ||(w f_R)'||^2
    floor = 1e-12 * max(float(variance.max()), 1e-300)
    norm = np.linalg.norm(G) * np.sqrt(np.maximum(variance, floor))
    values = np.where(variance > floor, cross.values / np.maximum(norm, 1e-300), 0.0)
    return CorrelationGrid(values, cross.alphas, cross.betas, cross.gammas)


def peaks(
    grid: CorrelationGrid, *, count: int = 8, min_separation: float = np.deg2rad(15.0)
) -> list[tuple[NDArray[np.float64], float]]:
    """The highest local maxima of the grid, as distinct rotations.

    Parameters
    ----------
    grid : CorrelationGrid
    count : int
        Hypotheses returned at most.
    min_separation : float
        Smallest angle (radians) between two returned rotations.

    Returns
    -------
    list of (ndarray (3, 3), float)
        Rotations and their correlation values, best first.
    """
    return [(grid.rotation(index), value)
            for index, value in peak_indices(grid, count=count, min_separation=min_separation)]


def peak_indices(
    grid: CorrelationGrid, *, count: int = 8, min_separation: float = np.deg2rad(15.0)
) -> list[tuple[tuple[int, int, int], float]]:
    """:func:`peaks` as the grid indices ``(beta, alpha, gamma)`` of the peaks and their
    values, best first: a peak's index names its rotation on every grid of the same
    samples (:meth:`CorrelationGrid.rotation`)."""
    v = grid.values
    # Local maxima over the 26 neighbours: alpha and gamma wrap around; beta ends at 0, pi.
    largest = maximum_filter(v, size=3, mode=("constant", "wrap", "wrap"), cval=-np.inf)
    is_peak = v >= largest
    order = np.argsort(v[is_peak])[::-1]
    indices = np.argwhere(is_peak)[order]
    chosen: list[tuple[tuple[int, int, int], float]] = []
    kept = np.empty((min(count, len(indices)), 3, 3))  # the chosen, tested against at once
    for index in map(tuple, indices.tolist()):
        R = grid.rotation(index)
        traces = np.einsum("ij,kij->k", R, kept[: len(chosen)])  # trace(R^T other)
        if np.all(np.arccos(np.clip((traces - 1.0) / 2.0, -1.0, 1.0)) >= min_separation):
            kept[len(chosen)] = R
            chosen.append((index, float(v[index])))
            if len(chosen) == count:
                break
    return chosen
