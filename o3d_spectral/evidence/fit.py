"""The fit of a pose: polished briefly, then the shares of the moving cloud's visible
points near the fixed cloud at one voxel and at a quarter voxel.

Two scales, two jobs. At one voxel (the *fit*, Open3D's ``fitness`` on the visible points)
a surface turned by a near-symmetry of the object (a box turned half a turn, a can about
its axis) still lies within a voxel of itself, so the fit tells whether the cloud is there
but not which of those poses is right; at a quarter voxel of the fixed surface's tangent
plane (the *closeness*) the polished right pose leaves the noise only, a near-symmetric one
the object's small asymmetries. The search's early confirmation
(:mod:`o3d_spectral.search.confirmation`) and the verification of the returned pose
(:mod:`o3d_spectral.evidence.verification`) both measure poses this way.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import open3d as o3d
from numpy.typing import NDArray

from ..io.rows import lengths
from ..law.stepper import MovingCloud, SpectralStepper
from ..refinement.icp import near_pose, point_to_plane_icp
from .constants import CLOSE_DISTANCE, ICP_DISTANCES

__all__ = ["Fit", "fit", "CLOSE_DISTANCE", "ICP_DISTANCES"]


class Fit(NamedTuple):
    """A pose polished and measured by :func:`fit`.

    Attributes
    ----------
    pose : ndarray, shape (4, 4)
        The polished pose (moving cloud to fixed cloud).
    share : float
        Its fit: the share of the visible points within one voxel of the fixed cloud.
    close : float
        Its closeness: the share within :data:`CLOSE_DISTANCE` voxels of the fixed
        surface's tangent plane at their nearest point.
    """

    pose: NDArray[np.float64]
    share: float
    close: float


def fit(
    stepper: SpectralStepper, moving: MovingCloud, fixed: o3d.geometry.PointCloud,
    pose: NDArray[np.float64], *, polish: bool = True,
) -> Fit:
    """Polish ``pose`` (4, 4) by the short ICP and measure its fit and closeness.

    Parameters
    ----------
    stepper : SpectralStepper
        For the visibility of the moving points (:meth:`SpectralStepper.visible`).
    moving : MovingCloud
        Its one-point-per-voxel points are polished.
    fixed : open3d.geometry.PointCloud
        The fixed cloud with normals, metres.
    pose : ndarray, shape (4, 4)
        Start of the polish.
    polish : bool
        False measures the fit at ``pose`` itself (a pose polished already).

    Returns
    -------
    Fit
        The polished pose, and the shares of the visible points within one voxel and
        within :data:`CLOSE_DISTANCE` voxels of ``fixed`` there.
    """
    voxel = stepper.voxel_size
    R, t = pose[:3, :3], pose[:3, 3]
    _, mask, _ = stepper.visible(moving, R, R @ moving.centroid + t - moving.centroid)
    points = moving.points if mask is None else moving.points[mask]
    near, kept = near_pose(fixed, points, pose, max(ICP_DISTANCES) * voxel)
    if len(kept) == 0:
        return Fit(pose, 0.0, 0.0)
    source = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    for distance in ICP_DISTANCES if polish else ():
        pose = point_to_plane_icp(source, near, distance * voxel, pose)
    measured = o3d.pipelines.registration.evaluate_registration(source, near, voxel, pose)
    pairs = np.asarray(measured.correspondence_set).reshape(-1, 2)  # nearest within a voxel
    posed = points[pairs[:, 0]] @ pose[:3, :3].T + pose[:3, 3]
    offsets = posed - np.asarray(near.points)[pairs[:, 1]]
    normals = np.asarray(near.normals)[pairs[:, 1]]
    along = np.einsum("ij,ij->i", offsets, normals) / np.maximum(lengths(normals), 1e-12)
    off_plane = np.abs(along)
    close = np.count_nonzero(off_plane < CLOSE_DISTANCE * voxel) / len(points)
    return Fit(pose, float(measured.fitness), float(close))
