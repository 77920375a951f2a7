"""The fit of a registration's pose and of its distinct rivals: the failure signal.

Open3D's ``fitness`` divides the source points near the target by all of them: a model
registered right onto a single view scores 0.3-0.6 (its back is not in the view), as
low as many wrong poses. :func:`verify` measures what the view can hold instead, as the
early confirmation does (:func:`o3d_spectral.evidence.fit.fit`), at the returned pose (the
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
distinct (:func:`o3d_spectral.evidence.poses.distinct`) are measured the same way where they
ended (the climbs' best iterates; the confirmation's rivals after its short ICP), and the
best of them is the *rival fit*. Both are reported in the result (``fit``, ``rival_fit``), and
the fit is one of the calibrated confidence's inputs (:mod:`o3d_spectral.evidence.pose`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import open3d as o3d
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from ..io.cloud import MIN_POINTS, extent
from ..io.rows import in_ball, known
from ..law.stepper import MovingCloud, SpectralStepper
from ..refinement.icp import near_pose
from ..spectra import so3
from .constants import (
    AMBIGUITY_MARGIN,
    AMBIGUITY_MIN_FIT,
    ASYMMETRIC,
    REGION_SLACK,
    RIVALS,
    TURN_ANGLES,
    TURN_POLISH,
    TURN_REACH,
    WHOLE_SHARE,
)
from .fit import fit
from .poses import distinct

__all__ = ["verify", "measure", "Verification", "ambiguity", "Ambiguity", "turns", "FixedPoints",
           "RIVALS",
           "AMBIGUITY_MARGIN", "AMBIGUITY_MIN_FIT", "TURN_ANGLES", "TURN_POLISH",
           "TURN_REACH", "ASYMMETRIC"]


class FixedPoints:
    """The fixed cloud and KD-trees of its points, built once for every fit that
    measures poses against it.

    A fit asks which points lie within a distance of the fixed cloud: only the fixed
    points within that distance of the ball holding the posed points can answer, so a
    tree of those alone answers exactly as a tree of the whole cloud would. Each tree
    holds the fixed points about one region, :data:`REGION_SLACK` times the ball and
    its distance, and serves every later fit whose ball and distance lie inside it (the
    returned pose, its turns and polished rivals about its centroid); where a region
    would hold more than :data:`WHOLE_SHARE` of the cloud, one tree of the whole cloud
    serves everything. An object's view against a scene builds a tree of the object's
    neighbourhood, not of the scene; two views of one object, one of the whole view.

    Parameters
    ----------
    cloud : open3d.geometry.PointCloud
        The fixed cloud with normals, metres.
    """

    def __init__(self, cloud: o3d.geometry.PointCloud) -> None:
        self.cloud = cloud
        self.points = np.asarray(cloud.points)
        self._regions: list[tuple[NDArray[np.float64], float, cKDTree]] = []

    def share(self, points: NDArray[np.float64], distance: float) -> float:
        """Share of ``points`` (K, 3, metres) within ``distance`` (metres) of the fixed
        points (0 when either holds none)."""
        if len(self.points) == 0 or len(points) == 0:
            return 0.0
        distances, _ = self._tree(points, distance).query(points, distance_upper_bound=distance)
        return float(np.mean(np.isfinite(distances)))

    def _tree(self, points: NDArray[np.float64], distance: float) -> cKDTree:
        """A tree of every fixed point within ``distance`` of ``points``' ball: a kept
        one whose region holds that ball, or a new one."""
        centre, radius = extent(points)
        reach = radius + distance
        for region_centre, region_reach, tree in self._regions:
            if float(np.linalg.norm(centre - region_centre)) + reach <= region_reach:
                return tree
        region_reach = REGION_SLACK * reach
        inside = in_ball(self.points, centre, region_reach)
        if np.count_nonzero(inside) > WHOLE_SHARE * len(self.points):
            inside, region_reach = slice(None), np.inf
        tree = cKDTree(self.points[inside])
        self._regions.append((centre, region_reach, tree))
        return tree


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
    measured = measure(stepper, moving, FixedPoints(fixed), pose, others, culls=culls)
    return measured.fit, measured.rival_fit


@dataclass(frozen=True)
class Verification:
    """A pose's fit and its best distinct rival's (:func:`measure`).

    Attributes
    ----------
    fit : float
        The pose's fit, [0, 1].
    rival_fit : float
        The best fit of a distinct hypothesis, [0, 1] (0 when none).
    rival : ndarray, shape (4, 4), or None
        That hypothesis (moving cloud to fixed cloud); None when none.
    """

    fit: float
    rival_fit: float = 0.0
    rival: NDArray[np.float64] | None = None


def measure(
    stepper: SpectralStepper, moving: MovingCloud, fixed: FixedPoints,
    pose: NDArray[np.float64], others: Sequence[NDArray[np.float64]] = (), *,
    culls: bool,
) -> Verification:
    """:func:`verify` on ``fixed``'s KD-tree, with the best rival's pose."""
    share = _share(stepper, moving, fixed, pose)
    best = Verification(_facing_share(stepper, moving, fixed, pose, share, culls))
    for other in list(others)[:RIVALS]:  # measured where they are: distinct ones only
        if distinct(other, pose):
            other_share = _share(stepper, moving, fixed, other)
            other_share = _facing_share(stepper, moving, fixed, other, other_share, culls)
            if best.rival is None or other_share > best.rival_fit:
                best = Verification(best.fit, other_share, other)
    return best


def _facing_share(
    stepper: SpectralStepper, moving: MovingCloud, fixed: FixedPoints,
    pose: NDArray[np.float64], share: float, culls: bool,
) -> float:
    """``share`` (:func:`o3d_spectral.evidence.fit.fit`'s), or, for two views (the moving
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
    return fixed.share(points[facing], stepper.voxel_size)


@dataclass(frozen=True)
class Ambiguity:
    """The best distinct pose found besides the returned one.

    Attributes
    ----------
    fit : float
        Its fit, [0, 1] (0 when none was found).
    angle : float
        The rotation between it and the returned pose, degrees (0 when none).
    ambiguous : bool
        It fits as well as the returned pose (within :data:`AMBIGUITY_MARGIN`), which
        fits at least :data:`AMBIGUITY_MIN_FIT`.
    self_match : float
        How far the turn from the returned pose to it maps the source onto itself: the
        median distance of the turned source points to the tangent plane of their
        nearest source point, in voxels (0 for an exact symmetry; :data:`ASYMMETRIC`
        and over: two poses that differ, which the target cannot tell apart); inf when
        none was found.
    pose : ndarray, shape (4, 4), or None
        That distinct pose (moving cloud to fixed cloud); None when none was found.
    """

    fit: float = 0.0
    angle: float = 0.0
    ambiguous: bool = False
    self_match: float = float("inf")
    pose: NDArray[np.float64] | None = None

    @property
    def symmetric(self) -> bool:
        """The rival is the returned pose turned by a symmetry of the source (within
        :data:`ASYMMETRIC`): both poses are equally right."""
        return self.self_match < ASYMMETRIC


def ambiguity(
    stepper: SpectralStepper, moving: MovingCloud, fixed: FixedPoints,
    pose: NDArray[np.float64], measured: Verification, *, culls: bool,
) -> Ambiguity:
    """The best distinct pose among the measured rival and the turns of ``pose``.

    Parameters
    ----------
    stepper, moving, fixed, culls
        As for :func:`verify`.
    pose : ndarray, shape (4, 4)
        The returned pose (moving cloud to fixed cloud).
    measured : Verification
        ``pose``'s :func:`measure` (its fit, and the search's best distinct hypothesis).

    Returns
    -------
    Ambiguity

    Notes
    -----
    The turns (:func:`turns`: a quarter and a half turn about each of the source's
    principal axes) are measured where they are, on the fixed cloud's points near the
    pose; the best is polished by the short ICP
    (:func:`o3d_spectral.evidence.fit.fit`) when it fits within
    :data:`TURN_POLISH` of the pose (a near-symmetric object lands a voxel or two off
    its other side), so the cost is a few distance queries and at most one polish.
    """
    best_fit, best = measured.rival_fit, measured.rival
    shares = [(_share(stepper, moving, fixed, turn), turn) for turn in turns(moving, pose)]
    share, turn = max(shares, key=lambda measured_turn: measured_turn[0])
    if share >= measured.fit - TURN_POLISH:
        # a turn about the points' centroid keeps them in their ball: the fixed points
        # within reach of a polish (and its drift) of that ball are all it can use
        near, _ = near_pose(fixed.cloud, moving.points, pose, TURN_REACH * stepper.voxel_size)
        polished = fit(stepper, moving, near, turn)
        if distinct(polished.pose, pose):
            share, turn = polished.share, polished.pose
    if distinct(turn, pose):
        share = _facing_share(stepper, moving, fixed, turn, share, culls)
        if best is None or share > best_fit:
            best_fit, best = share, turn
    if best is None:
        return Ambiguity()
    angle = float(np.rad2deg(so3.rotation_angle(pose[:3, :3].T @ best[:3, :3])))
    ambiguous = measured.fit >= AMBIGUITY_MIN_FIT and best_fit >= measured.fit - AMBIGUITY_MARGIN
    return Ambiguity(best_fit, angle, ambiguous,
                     _self_match(moving, np.linalg.inv(pose) @ best, stepper.voxel_size), best)


def _self_match(moving: MovingCloud, motion: NDArray[np.float64], voxel_size: float) -> float:
    """Median distance (voxels) of the moving points moved by ``motion`` (4, 4) to the
    tangent plane of their nearest moving point (those with a normal)."""
    has_normal = known(moving.point_normals)
    points, normals = moving.points[has_normal], moving.point_normals[has_normal]
    if len(points) < MIN_POINTS:
        return float("inf")
    moved = points @ motion[:3, :3].T + motion[:3, 3]
    _, nearest = cKDTree(points).query(moved)
    offsets = np.abs(np.einsum("ij,ij->i", moved - points[nearest], normals[nearest]))
    return float(np.median(offsets)) / voxel_size


def _share(
    stepper: SpectralStepper, moving: MovingCloud, fixed: FixedPoints,
    pose: NDArray[np.float64],
) -> float:
    """:func:`o3d_spectral.evidence.fit.fit`'s share at ``pose`` (4, 4) with no
    polish: of the moving points visible there, those within a voxel of ``fixed``."""
    R, t = pose[:3, :3], pose[:3, 3]
    _, mask, _ = stepper.visible(moving, R, R @ moving.centroid + t - moving.centroid)
    points = moving.points if mask is None else moving.points[mask]
    return fixed.share(points @ R.T + t, stepper.voxel_size)


def turns(moving: MovingCloud, pose: NDArray[np.float64]) -> list[NDArray[np.float64]]:
    """``pose`` (4, 4) turned a quarter turn each way and half a turn about each
    principal axis of the moving cloud's points through their centroid (before
    ``pose``): nine poses (4, 4)."""
    centre = moving.points.mean(axis=0)
    _, axes = np.linalg.eigh(np.cov((moving.points - centre).T))
    out = []
    for axis in axes.T:
        for angle in TURN_ANGLES:
            turn = np.eye(4)
            turn[:3, :3] = so3.exp(np.deg2rad(angle) * axis)
            turn[:3, 3] = centre - turn[:3, :3] @ centre
            out.append(pose @ turn)
    return out
