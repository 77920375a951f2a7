"""The fit of a registration's pose and of its distinct rivals: the failure signal.

Open3D's ``fitness`` divides the source points near the target by all of them: a model
registered right onto a single view scores 0.3-0.6 (its back is not in the view), as
low as many wrong poses. :func:`verify` measures what the view can hold instead, as the
early confirmation does (:func:`o3d_spectral.search.confirmation.fit`), at the returned pose (the
polish's: no further ICP, so the signal costs a few distance queries, not a search): its
*fit* is the share of the source's one-per-voxel
points that the target's sensor would see there (facing it,
:meth:`o3d_spectral.SpectralStepper.visible`; all of them against a whole cloud) lying
within one voxel of the target; between two views (two scans, matched whole), of those
facing the target's sensor, its overlap about. What the view does not show for other reasons (a part
hidden by an object the view left out, or beyond a crop's outline) still counts as
missed: a right pose of a model on a view missing half of it fits about half. Points
hidden behind what the view saw in front of them are not set apart: in a scene that
would set apart a wrong pose sunk into the table as much as an occluded right one.

The hypotheses of the global search that end over
distinct (:func:`o3d_spectral.search.poses.distinct`) are measured the same way where they
ended (the climbs' best iterates; the confirmation's rivals after its short ICP), and the
best of them is the *rival fit*. Both are reported in the result (``fit``, ``rival_fit``), and
the low-fit warning (:func:`o3d_spectral.diagnostics.low_fit`) is based on them.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import open3d as o3d
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from .io.cloud import MIN_POINTS
from .refinement import near_pose
from .search.confirmation import fit
from .search.poses import distinct
from .stepper import MovingCloud, SpectralStepper

__all__ = ["verify", "RIVALS"]

#: Hypotheses measured at most, besides the returned pose.
RIVALS = 4


def verify(
    stepper: SpectralStepper, moving: MovingCloud, fixed: o3d.geometry.PointCloud,
    pose: NDArray[np.float64], others: Sequence[NDArray[np.float64]] = (), *,
    culls: bool,
) -> tuple[float, float]:
    """The fit of ``pose`` and the best fit of a distinct one among ``others``.

    Parameters
    ----------
    stepper : SpectralStepper
        The fixed cloud's, for the visibility of the moving points.
    moving : MovingCloud
        The moving cloud; the poses act on its points.
    fixed : open3d.geometry.PointCloud
        The fixed cloud with normals, metres.
    pose : ndarray, shape (4, 4)
        The returned pose (moving cloud to fixed cloud).
    others : sequence of ndarray (4, 4)
        Other hypotheses, best first; the first :data:`RIVALS` are measured.
    culls : bool
        Whether the moving cloud is matched as the fixed cloud's sensor sees it
        (:attr:`o3d_spectral.search.situation.Situation.culls`); between two views it is
        not, and a fit counts the points facing the fixed sensor only.

    Returns
    -------
    (float, float)
        The fit of ``pose``, and the best fit of a hypothesis that turns the cloud over
        ``DISTINCT_ANGLE`` from ``pose`` (0 when there is none), each in [0, 1].
    """
    share = fit(stepper, moving, fixed, pose, polish=False).share
    rival = 0.0
    for other in list(others)[:RIVALS]:  # measured where they are: distinct ones only
        if distinct(other, pose):
            other_share = fit(stepper, moving, fixed, other, polish=False).share
            rival = max(rival, _facing_share(stepper, moving, fixed, other, other_share, culls))
    return _facing_share(stepper, moving, fixed, pose, share, culls), rival


def _facing_share(
    stepper: SpectralStepper, moving: MovingCloud, fixed: o3d.geometry.PointCloud,
    pose: NDArray[np.float64], share: float, culls: bool,
) -> float:
    """``share`` (:func:`o3d_spectral.search.confirmation.fit`'s), or, for two views (the moving
    cloud matched whole, though the fixed cloud's sensor is known), the share of the
    moving points facing that sensor at ``pose`` that lie within one voxel of ``fixed``:
    what the fixed view can hold of the moving one (their overlap, about), not all of it."""
    if stepper.viewpoint is None or culls or moving.reading.two_sided:
        return share
    R, t = pose[:3, :3], pose[:3, 3]
    points = moving.points @ R.T + t
    facing = np.einsum("ij,ij->i", moving.point_normals @ R.T, stepper.viewpoint - points) > 0
    if facing.sum() < MIN_POINTS:
        return share
    points = points[facing]
    near, _ = near_pose(fixed, points, np.eye(4), stepper.voxel_size)
    if len(near.points) == 0:
        return 0.0
    distances, _ = cKDTree(np.asarray(near.points)).query(
        points, distance_upper_bound=stepper.voxel_size)
    return float(np.mean(np.isfinite(distances)))
