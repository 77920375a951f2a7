"""Pose errors, plain and symmetry-aware (BOP convention).

Following the BOP benchmark (Hodan et al., ECCV 2020), a pose estimate ``T_est`` of a
symmetric object is as good as its best match among the equivalent ground truths
``T_gt @ S`` over the object's symmetry group (:class:`~o3d_spectral.synthetic.symmetry.Symmetry`);
the ``symmetric_*`` errors and :func:`mssd` minimise over the group, the plain errors do not.

All transforms are 4x4 float64 arrays mapping source points onto target points
(``target ~ T @ source``); rotations may also be passed as 3x3. Errors are in degrees
(rotation) and metres (translation, distances).

References
----------
T. Hodan, M. Sundermeyer, B. Drost et al., "BOP Challenge 2020 on 6D Object Localization",
ECCV Workshops 2020, doi:10.1007/978-3-030-66096-3_39.
"""

from __future__ import annotations

import numpy as np

from o3d_spectral.common.pose_errors import (
    angle_from_trace,
    as_rotation,
    as_transform,
    rotation_error,
    shifted,
    translation_error,
)
from o3d_spectral.synthetic.symmetry import Symmetry

__all__ = [
    "mssd",
    "rotation_error",
    "symmetric_rotation_error",
    "symmetric_translation_error",
    "translation_error",
]


def symmetric_rotation_error(T_est: np.ndarray, T_gt: np.ndarray, symmetry: Symmetry) -> float:
    """``min_S rotation_error(T_est, T_gt @ S)`` over the symmetry group (degrees).

    The minimum over a continuous axis is exact: with ``A = R_gt^T R_est D^T`` and
    ``C(theta)`` the rotation about unit axis ``a``,
    ``tr(C^T A) = a^T A a + p cos(theta) + q sin(theta)``, maximal at
    ``a^T A a + sqrt(p^2 + q^2)`` where ``p = tr(A) - a^T A a``, ``q = tr([a]_x^T A)``.

    Parameters
    ----------
    T_est, T_gt : ndarray, shape (4, 4)
        Estimated and true source-to-target transforms.
    symmetry : Symmetry
        The object's symmetry group in the source frame (e.g. ``Instance.symmetry``).
    """
    r_est, r_gt = as_rotation(T_est, "T_est"), as_rotation(T_gt, "T_gt")
    best = -np.inf
    for d in symmetry.discrete:
        a_mat = r_gt.T @ r_est @ d[:3, :3].T
        if symmetry.axis is None:
            best = max(best, np.trace(a_mat))
            continue
        a = symmetry.axis
        along = a @ a_mat @ a
        p = np.trace(a_mat) - along
        # tr([a]_x^T A) = a . (A_32 - A_23, A_13 - A_31, A_21 - A_12)
        q = a @ np.array(
            [a_mat[2, 1] - a_mat[1, 2], a_mat[0, 2] - a_mat[2, 0], a_mat[1, 0] - a_mat[0, 1]]
        )
        best = max(best, along + np.hypot(p, q))
    return angle_from_trace(best)


def symmetric_translation_error(
    T_est: np.ndarray, T_gt: np.ndarray, symmetry: Symmetry, *, center: np.ndarray | None = None
) -> float:
    """``min_S translation_error(T_est, T_gt @ S, center=center)`` over the symmetry group (m).

    The minimum over a continuous axis is exact: the translation of ``T_gt @ C(theta) @ D``
    runs on a circle about the axis, and the closest point of a circle is found in closed
    form. Translations depend on where the source frame's origin is: pass the object's
    centroid as ``center`` (see :func:`translation_error`), or use :func:`mssd`.
    """
    if center is not None:
        back = np.eye(4)
        back[:3, 3] = -np.asarray(center, dtype=np.float64).reshape(3)
        symmetry = symmetry.transformed(back)
    t_est = shifted(as_transform(T_est, "T_est"), center)
    t_gt = shifted(as_transform(T_gt, "T_gt"), center)
    # In the source frame: translation(T_gt @ C @ D) = t_gt + R_gt (c + R_C (t_D - c)).
    w = t_gt[:3, :3].T @ (t_est[:3, 3] - t_gt[:3, 3]) - symmetry.center
    best = np.inf
    for d in symmetry.discrete:
        v = d[:3, 3] - symmetry.center
        if symmetry.axis is None:
            best = min(best, np.linalg.norm(w - v))
            continue
        a = symmetry.axis
        w_perp, v_perp = w - (w @ a) * a, v - (v @ a) * a
        radial = np.linalg.norm(w_perp) - np.linalg.norm(v_perp)
        best = min(best, np.hypot(w @ a - v @ a, radial))
    return float(best)


def mssd(
    T_est: np.ndarray,
    T_gt: np.ndarray,
    points: np.ndarray,
    symmetry: Symmetry | None = None,
    *,
    step: float = np.deg2rad(1.0),
) -> float:
    """Maximum symmetry-aware surface distance (BOP's MSSD), in metres.

    ``min_S max_x ||T_est x - T_gt S x||`` over model points ``x``.

    Parameters
    ----------
    T_est, T_gt : ndarray, shape (4, 4)
        Estimated and true source-to-target transforms.
    points : ndarray, shape (N, 3)
        Model points in the source frame (m), e.g. the source cloud's points.
    symmetry : Symmetry, optional
        Group in the source frame; None for no symmetry.
    step : float, optional
        Sampling step (radians) of a continuous axis; the minimum is over this sampling.
    """
    t_est, t_gt = as_transform(T_est, "T_est"), as_transform(T_gt, "T_gt")
    points = np.asarray(points, dtype=float)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"points must have shape (N, 3), got {points.shape}")
    group = np.eye(4)[None] if symmetry is None else symmetry.elements(step=step)
    moved_est = points @ t_est[:3, :3].T + t_est[:3, 3]
    best = np.inf
    for s in t_gt @ group:
        moved_gt = points @ s[:3, :3].T + s[:3, 3]
        best = min(best, np.max(np.linalg.norm(moved_est - moved_gt, axis=1)))
    return float(best)
