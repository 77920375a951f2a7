"""From the control law's increment to joint velocities (paper, eq. robot_controller).

``qdot = J_c^+ Xdot_c``: the camera twist ``Xdot_c`` realising one cycle's increment, mapped
by the damped pseudo-inverse of the camera-frame Jacobian, then limited so no joint exceeds
its speed (the whole vector is scaled, so the camera keeps its direction) or leaves its
range within the next control period.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..spectra import so3

__all__ = [
    "se3_log",
    "camera_twist",
    "damped_pseudo_inverse",
    "joint_velocities",
    "limit_velocities",
]

_EPS = 1e-12


def se3_log(transform: ArrayLike) -> NDArray[np.float64]:
    """Twist ``(v, w)`` (6,) whose exponential is the rigid ``transform`` (4, 4).

    ``transform = expm([[hat(w), v], [0, 0]])``: moving with the constant body twist
    ``(v, w)`` for one unit of time performs ``transform``. ``v`` in metres, ``w`` in radians.
    """
    T = np.asarray(transform, dtype=np.float64)
    if T.shape != (4, 4):
        raise ValueError(f"transform must have shape (4, 4), got {T.shape}")
    w = so3.log(T[:3, :3])
    theta = float(np.linalg.norm(w))
    W = so3.hat(w)
    if theta < 1e-6:  # series of the inverse left Jacobian
        inverse_jacobian = np.eye(3) - 0.5 * W + W @ W / 12.0
    else:
        half = 0.5 * theta
        coefficient = (1.0 - half * np.cos(half) / np.sin(half)) / theta**2
        inverse_jacobian = np.eye(3) - 0.5 * W + coefficient * W @ W
    return np.concatenate([inverse_jacobian @ T[:3, 3], w])


def camera_twist(cloud_increment: ArrayLike, period: float) -> NDArray[np.float64]:
    """Camera body twist (6,) realising one cycle's increment in ``period`` seconds.

    Parameters
    ----------
    cloud_increment : array_like, shape (4, 4)
        ``Step.transformation``: how the captured cloud (camera frame) should move.
    period : float
        Control period, seconds.

    Returns
    -------
    ndarray, shape (6,)
        ``(v, w)``: linear (m/s) and angular (rad/s) velocity in the camera frame. The
        scene is static, so the camera moves by the inverse of the cloud's increment.
    """
    if not period > 0:
        raise ValueError(f"period must be > 0 s, got {period}")
    return se3_log(np.linalg.inv(np.asarray(cloud_increment, dtype=np.float64))) / period


def damped_pseudo_inverse(jacobian: ArrayLike, damping: float) -> NDArray[np.float64]:
    """``J^T (J J^T + damping^2 I)^-1`` (n, m) of a Jacobian (m, n).

    Equal to the Moore-Penrose pseudo-inverse far from singularities; near them it trades
    a small tracking error for bounded joint velocities (damped least squares).
    """
    J = np.asarray(jacobian, dtype=np.float64)
    if J.ndim != 2:
        raise ValueError(f"jacobian must be a 2D array, got shape {J.shape}")
    if not damping >= 0:
        raise ValueError(f"damping must be >= 0, got {damping}")
    return J.T @ np.linalg.solve(J @ J.T + damping**2 * np.eye(J.shape[0]), np.eye(J.shape[0]))


def joint_velocities(jacobian: ArrayLike, twist: ArrayLike, *, damping: float) -> NDArray:
    """Joint velocities (n,) that best realise ``twist`` (6,) with the camera Jacobian (6, n)."""
    return damped_pseudo_inverse(jacobian, damping) @ np.asarray(twist, dtype=np.float64)


def limit_velocities(
    qdot: ArrayLike,
    q: ArrayLike,
    *,
    velocity_limit: ArrayLike,
    lower: ArrayLike,
    upper: ArrayLike,
    period: float,
) -> NDArray[np.float64]:
    """Joint velocities within the speed and position limits for one period.

    The whole vector is first scaled so that no joint exceeds its ``velocity_limit``
    (direction preserved); then each joint is stopped at its range ``[lower, upper]`` so
    that ``q + period * qdot`` stays inside it.

    Parameters
    ----------
    qdot, q : array_like, shape (n,)
        Commanded velocities (rad/s) and current positions (rad).
    velocity_limit, lower, upper : array_like, shape (n,)
        Limits, rad/s and rad.
    period : float
        Control period, seconds.

    Returns
    -------
    ndarray, shape (n,)
    """
    qdot = np.asarray(qdot, dtype=np.float64)
    ratio = np.max(np.abs(qdot) / np.maximum(np.asarray(velocity_limit, float), _EPS))
    if ratio > 1.0:
        qdot = qdot / ratio
    q = np.asarray(q, dtype=np.float64)
    return np.clip(qdot, (np.asarray(lower) - q) / period, (np.asarray(upper) - q) / period)
