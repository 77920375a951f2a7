"""Real Wigner matrices ``U^l(R)`` and their generators ``u^l(e_k)``.

``U^l(R)`` is the matrix by which a rotation acts on degree-``l`` real spherical-harmonic
coefficients (paper, eq. real_fourier_transform_gr_simplified)::

    S^l(R x) = U^l(R) S^l(x)            for every unit vector x
    g(x) = f(R^T x)   <=>   G^l = U^l(R) F^l

``U^l`` is a representation of SO(3) by orthogonal matrices:
``U^l(R1 R2) = U^l(R1) U^l(R2)``. Its generators (paper, eq. ul_derivative)
``u^l(e_k) = d/de U^l(exp(e hat(e_k)))`` at ``e = 0`` are constant antisymmetric
matrices, obtained from the angular-momentum operators ``L_k`` in the complex basis by
the complex-to-real change of basis ``T^l``: ``u^l_k = i T^l L_k^T (T^l)^H``.

All arrays use the padded layout of :mod:`o3d_spectral.spectra.harmonics`: the matrices for all
degrees ``l < B`` are stacked as shape ``(B, 2B - 1, 2B - 1)``, the block of degree ``l``
centred, zeros elsewhere. A rotation is evaluated as
``U(R) = Uz(alpha) Q Uz(beta) Q^T Uz(gamma)`` from its ZYZ Euler angles, where ``Uz`` (a
rotation about z) mixes orders ``m`` and ``-m`` only and ``Q = U(Rx(-pi/2))`` turns a
rotation about z into one about y (the usual fast route, one matrix product per degree).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from . import so3

__all__ = ["generators", "wigner_matrices", "rotate_coefficients", "wigner_z", "quarter_turn"]


def _complex_to_real(l: int) -> NDArray[np.complex128]:  # noqa: E741
    """``T^l`` with ``S^l = T^l Y^l`` (``Y^l``: complex harmonics, Condon-Shortley phase)."""
    T = np.zeros((2 * l + 1, 2 * l + 1), dtype=np.complex128)
    T[l, l] = 1.0
    r = 1.0 / np.sqrt(2.0)
    for m in range(1, l + 1):
        T[l + m, l - m] = r
        T[l + m, l + m] = (-1) ** m * r
        T[l - m, l - m] = 1j * r
        T[l - m, l + m] = -1j * (-1) ** m * r
    return T


def _angular_momentum(l: int) -> tuple[NDArray[np.complex128], ...]:  # noqa: E741
    """``(L_x, L_y, L_z)`` in the basis ``|l, m>``, ``m = -l..l``: ``M[m', m] = <m'|L|m>``."""
    m = np.arange(-l, l + 1)
    raise_ = np.diag(np.sqrt(l * (l + 1) - m[:-1] * (m[:-1] + 1.0)), -1)  # <m+1|L+|m>
    lower = raise_.T
    Lx = (raise_ + lower) / 2.0
    Ly = (raise_ - lower) / 2.0j
    return Lx.astype(np.complex128), Ly, np.diag(m).astype(np.complex128)


def _embed(blocks: list[NDArray[np.float64]], bandwidth: int) -> NDArray[np.float64]:
    out = np.zeros((bandwidth, 2 * bandwidth - 1, 2 * bandwidth - 1))
    for l, block in enumerate(blocks):  # noqa: E741
        s = slice(bandwidth - 1 - l, bandwidth + l)
        out[l, s, s] = block
    return out


@lru_cache(maxsize=16)
def generators(bandwidth: int) -> NDArray[np.float64]:
    """Generators ``u^l(e_k)`` for ``k = x, y, z`` and all ``l < B``.

    Returns
    -------
    ndarray, shape (3, B, 2B - 1, 2B - 1), read-only
        Real antisymmetric; ``expm(sum_k w_k u^l_k) = U^l(exp(hat(w))``.
    """
    blocks: list[list[NDArray[np.float64]]] = [[], [], []]
    for l in range(bandwidth):  # noqa: E741
        T = _complex_to_real(l)
        for k, L in enumerate(_angular_momentum(l)):
            u = 1j * T @ L.T @ T.conj().T
            assert np.abs(u.imag).max() < 1e-12
            blocks[k].append(u.real)
    out = np.stack([_embed(b, bandwidth) for b in blocks])
    out.flags.writeable = False
    return out


@lru_cache(maxsize=16)
def quarter_turn(bandwidth: int) -> NDArray[np.float64]:
    """``Q = U(Rx(-pi/2))``, which maps the z-axis to the y-axis; shape (B, 2B-1, 2B-1)."""
    ux = generators(bandwidth)[0]
    blocks = []
    for l in range(bandwidth):  # noqa: E741
        s = slice(bandwidth - 1 - l, bandwidth + l)
        blocks.append(scipy.linalg.expm(-np.pi / 2 * ux[l, s, s]))
    Q = _embed(blocks, bandwidth)
    Q.flags.writeable = False
    return Q


def _orders(bandwidth: int) -> NDArray[np.float64]:
    return np.arange(-(bandwidth - 1), bandwidth, dtype=np.float64)


def _z_left(angle: float, M: NDArray[np.float64]) -> NDArray[np.float64]:
    """``Uz(angle) @ M`` for stacked ``M`` of shape (B, 2B-1, ...)."""
    m = _orders(M.shape[0])
    shape = (1, -1) + (1,) * (M.ndim - 2)
    return np.cos(m * angle).reshape(shape) * M - np.sin(m * angle).reshape(shape) * M[:, ::-1]


def _z_right(M: NDArray[np.float64], angle: float) -> NDArray[np.float64]:
    """``M @ Uz(angle)`` for stacked ``M`` of shape (B, 2B-1, 2B-1)."""
    m = _orders(M.shape[0])
    return np.cos(m * angle) * M + np.sin(m * angle) * M[:, :, ::-1]


def wigner_z(angle: float, bandwidth: int) -> NDArray[np.float64]:
    """``U^l(Rz(angle))`` for all ``l < B``, shape (B, 2B - 1, 2B - 1); angle in radians."""
    eye = _embed([np.eye(2 * l + 1) for l in range(bandwidth)], bandwidth)  # noqa: E741
    return _z_left(angle, eye)


def wigner_matrices(R: ArrayLike, bandwidth: int) -> NDArray[np.float64]:
    """Real Wigner matrices ``U^l(R)`` for all degrees ``l < B``.

    Parameters
    ----------
    R : array_like, shape (3, 3)
        Rotation matrix.
    bandwidth : int
        ``B``.

    Returns
    -------
    ndarray, shape (B, 2B - 1, 2B - 1)
        Orthogonal blocks in the padded layout (module docstring).
    """
    alpha, beta, gamma = so3.euler_zyz(R)
    Q = quarter_turn(bandwidth)
    inner = _z_left(beta, _z_right(Q.transpose(0, 2, 1), gamma))
    return _z_left(alpha, Q @ inner)


def rotate_coefficients(coefficients: ArrayLike, R: ArrayLike) -> NDArray[np.float64]:
    """Coefficients of ``x -> f(R^T x)`` from those of ``f``: ``G^l = U^l(R) F^l``.

    Parameters
    ----------
    coefficients : array_like, shape (B, 2B - 1)
    R : array_like, shape (3, 3)

    Returns
    -------
    ndarray, shape (B, 2B - 1)
    """
    F = np.asarray(coefficients, dtype=np.float64)
    U = wigner_matrices(R, F.shape[0])
    return np.einsum("lmn,ln->lm", U, F)
