"""Pose errors between two rigid transforms: rotation angle and translation distance.

All transforms are 4x4 float64 arrays mapping source points onto target points
(``target ~ T @ source``); rotations may also be passed as 3x3. Errors are in degrees
(rotation) and metres (translation). The symmetry-aware errors, which minimise over an
object's symmetry group, build on these in :mod:`o3d_spectral.harness.errors`.
"""

from __future__ import annotations

import numpy as np

__all__ = ["rotation_error", "translation_error"]


def as_rotation(transform: np.ndarray, name: str) -> np.ndarray:
    """The 3x3 rotation of a 3x3 or 4x4 ``transform``; ``ValueError`` naming ``name``."""
    transform = np.asarray(transform, dtype=float)
    if transform.shape not in ((3, 3), (4, 4)):
        raise ValueError(f"{name} must be 3x3 or 4x4, got shape {transform.shape}")
    return transform[:3, :3]


def as_transform(transform: np.ndarray, name: str) -> np.ndarray:
    """``transform`` as a 4x4 float array; ``ValueError`` naming ``name`` otherwise."""
    transform = np.asarray(transform, dtype=float)
    if transform.shape != (4, 4):
        raise ValueError(f"{name} must be 4x4, got shape {transform.shape}")
    return transform


def angle_from_trace(trace: np.ndarray | float) -> float:
    """The angle (degrees) of a rotation whose trace is ``trace``."""
    return float(np.rad2deg(np.arccos(np.clip((trace - 1.0) / 2.0, -1.0, 1.0))))


def rotation_error(T_est: np.ndarray, T_gt: np.ndarray) -> float:
    """Angle of ``R_gt^T R_est`` in degrees: ``arccos((tr(R_gt^T R_est) - 1) / 2)``.

    Parameters
    ----------
    T_est, T_gt : ndarray, shape (4, 4) or (3, 3)
        Estimated and true source-to-target transforms (only the rotations are used).

    Returns
    -------
    float
        Error in degrees, in [0, 180].
    """
    r_est, r_gt = as_rotation(T_est, "T_est"), as_rotation(T_gt, "T_gt")
    return angle_from_trace(np.trace(r_gt.T @ r_est))


def shifted(transform: np.ndarray, center: np.ndarray | None) -> np.ndarray:
    """``transform @ Tr(center)``: the motion seen from a source frame centred on ``center``."""
    if center is None:
        return transform
    shift = np.eye(4)
    shift[:3, 3] = np.asarray(center, dtype=np.float64).reshape(3)
    return transform @ shift


def translation_error(
    T_est: np.ndarray, T_gt: np.ndarray, *, center: np.ndarray | None = None
) -> float:
    """Distance (m) between where two 4x4 transforms put the source point ``center``.

    Parameters
    ----------
    T_est, T_gt : ndarray, shape (4, 4)
    center : ndarray, shape (3,), optional
        Source point (m) at which the error is measured; the source frame's origin when
        omitted (the difference of the translations). The object's centroid makes the
        error independent of where the source frame's origin lies: far from the object,
        the origin turns every rotation error into a large translation error.
    """
    t_est = shifted(as_transform(T_est, "T_est"), center)
    t_gt = shifted(as_transform(T_gt, "T_gt"), center)
    return float(np.linalg.norm(t_est[:3, 3] - t_gt[:3, 3]))
