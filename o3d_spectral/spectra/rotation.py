"""Rotation by correlating EGIs on SO(3) (paper, eqs. correlation_rotation to cr_derivative).

With ``F^l`` the coefficients of the moving EGI and ``G^l`` those of the fixed one::

    C_r(R) = 1/(4 pi) sum_l (G^l)^T U^l(R) F^l                      (correlation_rotation)
    grad C_r(R)_k = 1/(4 pi) sum_l (G^l)^T U^l(R) u^l(e_k) F^l       (cr_derivative)

the gradient being taken for a right perturbation ``R exp(e hat(e_k))``. The second
derivatives (same form, with ``(u_j u_k + u_k u_j) / 2``) give the local curvature, which
:func:`rotation_step` uses to turn the gradient into a step in radians.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .wigner import generators, wigner_matrices

__all__ = ["RotationGradient", "correlation", "gradient", "rotation_cost", "curvature_scale",
           "rotation_step"]

_FOUR_PI = 4.0 * np.pi


@dataclass(frozen=True)
class RotationGradient:
    """Correlation and its first and second derivatives at one rotation.

    Attributes
    ----------
    value : float
        ``C_r(R)``.
    gradient : ndarray, shape (3,)
        ``grad C_r(R, e_k)``, k = x, y, z (per radian).
    hessian : ndarray, shape (3, 3)
        Symmetrised second derivative for right perturbations (per radian squared).
    """

    value: float
    gradient: NDArray[np.float64]
    hessian: NDArray[np.float64]


def _rotated_target(G: NDArray[np.float64], R: ArrayLike) -> NDArray[np.float64]:
    """``U(R)^T G`` per degree: the fixed EGI brought back by ``R^T``."""
    U = wigner_matrices(R, G.shape[0])
    return np.einsum("lmn,lm->ln", U, G)


def correlation(F: ArrayLike, G: ArrayLike, R: ArrayLike) -> float:
    """``C_r(R)`` (eq. correlation_rotation); ``F``, ``G`` of shape (B, 2B - 1)."""
    F, G = np.asarray(F, dtype=np.float64), np.asarray(G, dtype=np.float64)
    return float(np.sum(_rotated_target(G, R) * F) / _FOUR_PI)


def gradient(F: ArrayLike, G: ArrayLike, R: ArrayLike) -> RotationGradient:
    """``C_r``, its gradient (eq. cr_derivative) and Hessian at ``R``.

    Parameters
    ----------
    F, G : array_like, shape (B, 2B - 1)
        Coefficients of the moving and the fixed EGI.
    R : array_like, shape (3, 3)

    Returns
    -------
    RotationGradient
    """
    F, G = np.asarray(F, dtype=np.float64), np.asarray(G, dtype=np.float64)
    u = generators(F.shape[0])
    V = _rotated_target(G, R)  # (B, 2B-1)
    uF = np.einsum("klmn,ln->klm", u, F)  # u_k F, (3, B, 2B-1)
    uV = np.einsum("klmn,lm->kln", u, V)  # u_k^T V = -u_k V
    grad = np.einsum("lm,klm->k", V, uF) / _FOUR_PI
    # V^T u_j u_k F = (u_j^T V) . (u_k F)
    second = np.einsum("jlm,klm->jk", uV, uF) / _FOUR_PI
    return RotationGradient(float(np.sum(V * F) / _FOUR_PI), grad, 0.5 * (second + second.T))


def rotation_cost(F: ArrayLike, G: ArrayLike, R: ArrayLike) -> float:
    """``J_r(R) = 1/2 ||g_r - f_r(R^T .)||^2`` (eq. rotation_cost_function).

    The basis is orthonormal, so the L2 norm on the sphere is the coefficients' norm.
    """
    F, G = np.asarray(F, dtype=np.float64), np.asarray(G, dtype=np.float64)
    U = wigner_matrices(R, F.shape[0])
    return float(0.5 * np.sum((G - np.einsum("lmn,ln->lm", U, F)) ** 2))


def curvature_scale(F: ArrayLike, G: ArrayLike) -> float:
    """Mean curvature of ``C_r`` per axis at a perfect match, per radian squared.

    For ``G = U(R*) F`` the Hessian's trace at ``R*`` is
    ``-1/(4 pi) sum_l l(l+1) |F^l|^2`` (the Casimir identity ``sum_k (u^l_k)^2 = -l(l+1)``);
    this returns a third of it, with ``|F^l||G^l|`` in place of ``|F^l|^2``.
    """
    F, G = np.asarray(F, dtype=np.float64), np.asarray(G, dtype=np.float64)
    l = np.arange(F.shape[0])  # noqa: E741
    norms = np.linalg.norm(F, axis=1) * np.linalg.norm(G, axis=1)
    return float(np.sum(l * (l + 1) * norms) / (3.0 * _FOUR_PI))


def rotation_step(
    local: RotationGradient, scale: float, *, preconditioned: bool = True, floor: float = 1e-3
) -> NDArray[np.float64]:
    """Gradient of ``C_r`` turned into a rotation vector (radians): the full step.

    The paper's law is ``R <- R exp(lambda_r hat(grad C_r))``. Dividing the gradient by the
    curvature ``scale`` (:func:`curvature_scale`) makes it an angle, so that
    ``lambda_r`` is the fraction of the remaining error closed per iteration whatever the
    cloud. With ``preconditioned``, the gradient is divided by the local curvature
    instead, axis by axis (a Newton step): axes about which the EGI is nearly symmetric
    (the axis of a mug, whose handle alone fixes the rotation) then converge as fast as
    the others, and the step's length is the remaining error. The curvature's absolute
    value is used (a "saddle-free" Newton step, Dauphin et al. 2014), so the step always
    climbs, also where ``C_r`` is not concave; curvatures are floored at
    ``floor * scale``.

    Parameters
    ----------
    local : RotationGradient
    scale : float
        Positive curvature scale, per radian squared.
    preconditioned : bool
    floor : float
        Smallest curvature used, as a fraction of ``scale``.

    Returns
    -------
    ndarray, shape (3,)
    """
    if not preconditioned:
        return local.gradient / scale
    eigenvalues, vectors = np.linalg.eigh(-local.hessian)
    curvature = np.maximum(np.abs(eigenvalues), floor * scale)
    return vectors @ ((vectors.T @ local.gradient) / curvature)
