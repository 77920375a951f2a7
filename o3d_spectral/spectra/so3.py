"""Rotations and rigid motions: the hat map, exponential and logarithm on SO(3), ZYZ Euler
angles, a rotation about a pivot.

Conventions (see ``docs/conventions.md``): rotations are active, right-handed, angles in
radians; ``hat(w) @ v == cross(w, v)``; ``R = Rz(alpha) @ Ry(beta) @ Rz(gamma)`` for ZYZ
Euler angles (paper, eq. euler_representation).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "hat",
    "exp",
    "log",
    "rotation_angle",
    "euler_zyz",
    "uniform_rotations",
    "from_euler_zyz",
    "is_rotation",
    "project_to_rotation",
    "about_pivot",
]

_EPS = 1e-12


def hat(w: ArrayLike) -> NDArray[np.float64]:
    """Skew-symmetric matrix of a 3-vector: ``hat(w) @ v == np.cross(w, v)``.

    Parameters
    ----------
    w : array_like, shape (3,)

    Returns
    -------
    ndarray, shape (3, 3)
    """
    x, y, z = np.asarray(w, dtype=np.float64)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def exp(w: ArrayLike) -> NDArray[np.float64]:
    """Rotation ``exp(hat(w))`` by Rodrigues' formula.

    Parameters
    ----------
    w : array_like, shape (3,)
        Rotation vector: axis times angle (radians).

    Returns
    -------
    ndarray, shape (3, 3)
    """
    w = np.asarray(w, dtype=np.float64)
    theta = float(np.linalg.norm(w))
    K = hat(w)
    if theta < 1e-8:  # second-order Taylor expansion
        return np.eye(3) + K + 0.5 * K @ K
    return (
        np.eye(3)
        + (np.sin(theta) / theta) * K
        + ((1.0 - np.cos(theta)) / theta**2) * K @ K
    )


def log(R: ArrayLike) -> NDArray[np.float64]:
    """Rotation vector ``w`` with ``exp(w) == R`` and ``|w| <= pi``.

    Parameters
    ----------
    R : array_like, shape (3, 3)
        A rotation matrix.

    Returns
    -------
    ndarray, shape (3,)
        Axis times angle (radians). At an angle of exactly pi the sign of the axis is
        arbitrary (both signs give the same rotation).
    """
    R = np.asarray(R, dtype=np.float64)
    cos_theta = np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)
    theta = float(np.arccos(cos_theta))
    v = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    if theta < 1e-6:
        return 0.5 * v
    if np.pi - theta > 1e-4:
        return theta / (2.0 * np.sin(theta)) * v
    # Near pi, sin(theta) vanishes: take the axis from the symmetric part R + R^T = 2 a a^T + ...
    B = 0.5 * (R + R.T) - cos_theta * np.eye(3)
    axis = B[np.argmax(np.diag(B))]
    axis /= np.linalg.norm(axis)
    if axis @ v < 0.0:
        axis = -axis
    return theta * axis


def rotation_angle(R: ArrayLike) -> float:
    """Angle (radians, in [0, pi]) of the rotation ``R``, shape (3, 3)."""
    R = np.asarray(R, dtype=np.float64)
    return float(np.arccos(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)))


#: The super-Fibonacci spiral's second constant: the real root of ``psi^4 = psi + 4``.
_SUPER_FIBONACCI_PSI = 1.533751168755204288118041


def uniform_rotations(count: int) -> NDArray[np.float64]:
    """``count`` rotations spread evenly over SO(3), the same on every call: a
    super-Fibonacci spiral of unit quaternions (Alexa, "Super-Fibonacci spirals: fast,
    low-discrepancy sampling of SO(3)", CVPR 2022). Every rotation lies within about
    ``3.9 / count^(1/3)`` radians of one of them (1000: 22 degrees at most, 12 at the
    median).

    Returns
    -------
    ndarray, shape (count, 3, 3)
    """
    s = np.arange(count, dtype=np.float64) + 0.5
    r, r_rest = np.sqrt(s / count), np.sqrt(1.0 - s / count)
    alpha, beta = 2.0 * np.pi * s / np.sqrt(2.0), 2.0 * np.pi * s / _SUPER_FIBONACCI_PSI
    x, y = r * np.sin(alpha), r * np.cos(alpha)
    z, w = r_rest * np.sin(beta), r_rest * np.cos(beta)
    return np.stack([  # the unit quaternion (x, y, z, w) as a matrix
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
    ], axis=-2)


def euler_zyz(R: ArrayLike) -> tuple[float, float, float]:
    """ZYZ Euler angles ``(alpha, beta, gamma)`` with ``R = Rz(alpha) Ry(beta) Rz(gamma)``.

    Parameters
    ----------
    R : array_like, shape (3, 3)

    Returns
    -------
    alpha, gamma : float
        In (-pi, pi], radians.
    beta : float
        In [0, pi], radians. At ``beta`` = 0 or pi only ``alpha +- gamma`` is defined:
        ``gamma`` is then set to 0.
    """
    R = np.asarray(R, dtype=np.float64)
    beta = float(np.arctan2(np.hypot(R[2, 0], R[2, 1]), R[2, 2]))
    if np.hypot(R[0, 2], R[1, 2]) > 1e-9 and np.hypot(R[2, 0], R[2, 1]) > 1e-9:
        alpha = float(np.arctan2(R[1, 2], R[0, 2]))
        gamma = float(np.arctan2(R[2, 1], -R[2, 0]))
    elif R[2, 2] > 0:  # beta = 0: R = Rz(alpha + gamma)
        alpha, gamma = float(np.arctan2(R[1, 0], R[0, 0])), 0.0
    else:  # beta = pi: R = Rz(alpha - gamma) Ry(pi)
        alpha, gamma = float(np.arctan2(-R[1, 0], -R[0, 0])), 0.0
    return alpha, beta, gamma


def from_euler_zyz(alpha: float, beta: float, gamma: float) -> NDArray[np.float64]:
    """Rotation ``Rz(alpha) @ Ry(beta) @ Rz(gamma)`` (radians), shape (3, 3)."""
    return exp([0.0, 0.0, alpha]) @ exp([0.0, beta, 0.0]) @ exp([0.0, 0.0, gamma])


def is_rotation(R: ArrayLike, atol: float = 1e-6) -> bool:
    """True when ``R`` (3, 3) is finite, orthogonal and has determinant +1."""
    R = np.asarray(R, dtype=np.float64)
    return bool(
        R.shape == (3, 3)
        and np.all(np.isfinite(R))
        and np.allclose(R.T @ R, np.eye(3), atol=atol)
        and abs(np.linalg.det(R) - 1.0) < atol
    )


def project_to_rotation(M: ArrayLike) -> NDArray[np.float64]:
    """Nearest rotation (Frobenius norm) to a 3x3 matrix, by SVD.

    Used to remove round-off drift after many compositions.
    """
    U, _, Vt = np.linalg.svd(np.asarray(M, dtype=np.float64))
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
    return U @ D @ Vt


def about_pivot(
    R: ArrayLike, T: ArrayLike, pivot: ArrayLike
) -> NDArray[np.float64]:
    """The rigid motion ``x -> R (x - pivot) + pivot + T`` as a 4x4 matrix.

    ``R`` (3, 3) turns about ``pivot`` (3,) and ``T`` (3,) then shifts (metres): the
    control law's pose about the moving cloud's centroid (paper, Algorithm 1).
    """
    R, pivot = np.asarray(R, dtype=np.float64), np.asarray(pivot, dtype=np.float64)
    out = np.eye(4)
    out[:3, :3] = R
    out[:3, 3] = pivot + np.asarray(T, dtype=np.float64) - R @ pivot
    return out
