"""The compiled sum of spherical harmonics over many directions (numba), which numpy
would make through a (B, B, N) table of Legendre functions.

Compiled on first use and cached on disk as :mod:`o3d_spectral.spectra.kernels`' loops,
which compiles it ahead with them (:func:`o3d_spectral.spectra.kernels.compile_all`).
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import NDArray

from .constants import HARMONIC_BLOCK

__all__ = ["harmonic_sums", "HARMONIC_BLOCK"]


@numba.njit(cache=True, nogil=True)
def _legendre_factors(B: int) -> tuple[NDArray, NDArray, NDArray]:
    """Factors of the orthonormal Legendre recurrence
    (:func:`o3d_spectral.spectra.harmonics.legendre`): sectoral ``c[m]``, and ``a[l, m]``,
    ``b[l, m]`` of ``P_l^m = a (x P_{l-1}^m - b P_{l-2}^m)``."""
    c = np.empty(B)
    c[0] = np.sqrt(1.0 / (4.0 * np.pi))
    for m in range(1, B):
        c[m] = c[m - 1] * np.sqrt((2 * m + 1) / (2.0 * m))
    a, b = np.zeros((B, B)), np.zeros((B, B))
    for l in range(2, B):  # noqa: E741
        for m in range(l - 1):
            a[l, m] = np.sqrt((4.0 * l * l - 1.0) / (l * l - m * m))
            b[l, m] = np.sqrt(((l - 1) ** 2 - m * m) / (4.0 * (l - 1) ** 2 - 1.0))
    return c, a, b


@numba.njit(cache=True, nogil=True)
def harmonic_sums(directions: NDArray, weights: NDArray, B: int) -> NDArray:
    """``F_lm = sum_i w_i S_lm(n_i)`` for ``l < B``
    (:func:`o3d_spectral.spectra.harmonics.project`).

    The orthonormal Legendre recurrence runs over blocks of :data:`HARMONIC_BLOCK`
    directions at once, each block's terms summed in order before they are added to
    ``F`` (equal to a one-direction-at-a-time loop to rounding, and the same bits on
    every CPU: no fast-math, see :mod:`o3d_spectral.spectra.kernels`).

    Parameters
    ----------
    directions : ndarray, shape (N, 3)
        Unit vectors.
    weights : ndarray, shape (N,)
    B : int
        Bandwidth.

    Returns
    -------
    ndarray, shape (B, 2B - 1)
        Orders ``m >= 0`` (cosine terms) at column ``B - 1 + m``, ``m < 0`` (sine terms of
        ``|m|``) at ``B - 1 - |m|``.
    """
    F = np.zeros((B, 2 * B - 1))
    c, a, b = _legendre_factors(B)
    K = HARMONIC_BLOCK
    x, s, cu, su = np.empty(K), np.empty(K), np.empty(K), np.empty(K)
    cm, sm, sine_power = np.empty(K), np.empty(K), np.empty(K)
    wc, ws, p, before = np.empty(K), np.empty(K), np.empty(K), np.empty(K)
    for first in range(0, directions.shape[0], K):
        k = min(K, directions.shape[0] - first)
        for j in range(k):
            i = first + j
            x[j] = min(max(directions[i, 2], -1.0), 1.0)
            s[j] = np.sqrt(max(1.0 - x[j] * x[j], 0.0))
            rho = np.hypot(directions[i, 0], directions[i, 1])
            cu[j], su[j] = 1.0, 0.0  # (cos phi, sin phi); phi = 0 at the poles
            if rho > 1e-15:
                cu[j], su[j] = directions[i, 0] / rho, directions[i, 1] / rho
            cm[j], sm[j], sine_power[j] = 1.0, 0.0, 1.0  # cos(m phi), sin(m phi), sin^m
        for m in range(B):
            scale = np.sqrt(2.0) if m > 0 else 1.0
            for j in range(k):
                if m > 0:
                    cosine_m = cm[j] * cu[j] - sm[j] * su[j]
                    sm[j] = cm[j] * su[j] + sm[j] * cu[j]
                    cm[j] = cosine_m
                    sine_power[j] *= s[j]
                w = weights[first + j] * scale
                wc[j], ws[j] = w * cm[j], w * sm[j]
                before[j] = 0.0  # P_{l-1}^m and P_l^m, from l = m
                p[j] = c[m] * sine_power[j]
            for l in range(m, B):  # noqa: E741
                if l == m + 1:
                    first_step = np.sqrt(2.0 * m + 3.0)
                    for j in range(k):
                        before[j] = p[j]
                        p[j] = first_step * x[j] * before[j]
                elif l > m + 1:
                    a_lm, b_lm = a[l, m], b[l, m]  # scalars: the loop below vectorises
                    for j in range(k):
                        previous = p[j]
                        p[j] = a_lm * (x[j] * previous - b_lm * before[j])
                        before[j] = previous
                cosine, sine = 0.0, 0.0
                for j in range(k):
                    cosine += p[j] * wc[j]
                    sine += p[j] * ws[j]
                F[l, B - 1 + m] += cosine
                if m > 0:
                    F[l, B - 1 - m] += sine
    return F
