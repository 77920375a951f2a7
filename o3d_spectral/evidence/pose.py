"""What a pose's fit to the target says about whether it is right: the confidence's inputs.

A registration's final pose is measured once, at the end of the call
(:func:`o3d_spectral.run.finish`), on the clouds as the method holds them (one point per
voxel of the source, the target's down-sampled points near the pose), so the cost is a
few distance queries on one KD-tree:

- the *fit* (:mod:`o3d_spectral.evidence.verification`): the share of the source points the
  target could show lying within a voxel of it;
- the *target fit*: the share of the target's points inside the ball of the posed source
  that lie within a voxel of the source (a wrong object leaves much of the target
  unexplained; a crop of a right object leaves none);
- the *plane distance*: the median distance of the source inliers to the tangent plane
  of their nearest target point, in voxels (a right pose lies on the surface, a wrong
  one that happens to be near it crosses it);
- the *normal agreement*: the share of inliers whose normal is within
  :data:`NORMAL_AGREEMENT_ANGLE` of their target point's;
- the *motion support*: the least share, over every rigid motion, of the constraint the
  source points the target could show put on that motion that their inliers carry
  (Gelfand et al.'s geometric stability of point-to-plane alignment, 2003). Each point
  with normal ``n`` at ``p`` resists a motion (rotation ``w``, translation ``u``) by
  ``((p - c) x n) . w + n . u``; the inliers' share of the squares' sum is about the fit
  for most motions. A mug turned about its body's axis keeps the body's points on the
  body: only the handle resists that turn, and where the handle misses, the inliers
  carry almost none of it while the fit stays high. A motion no point resists (a can's
  turn about its axis, a symmetry) has no share to miss
  (:data:`~o3d_spectral.evidence.free_motions.SUPPORT_FLOOR`);
- the *free motions* (:mod:`o3d_spectral.evidence.free_motions`): the motions those inliers barely
  resist that go on with their fit unchanged farther than a pose's tolerance, and whether
  the whole source resists them (a symmetry of the source where it does not);
- the *free-space violation*, only where the target is a single view whose sensor was
  located: the share of the source points facing that sensor (squarely, not at grazing
  rays) that lie in front of what the sensor saw along their ray (the sensor saw through
  them: the pose cannot be right).
  Where the sensor is unknown (a whole model, a crop, a two-sided cloud) it is None: a
  guessed sensor on a crop sees "through" the cut and makes false hits.

:mod:`o3d_spectral.evidence.confidence` turns these into a probability.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import scipy.linalg
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from ..io.cloud import MIN_POINTS
from ..io.rows import known
from .constants import (
    FREE_SPACE_DEPTH,
    MIN_INCIDENCE,
    NORMAL_AGREEMENT_ANGLE,
    RAY_NEIGHBOURS,
    RAY_RADIUS,
)
from .free_motions import FreeMotion, constraint_rows, free_motions, support_floor

__all__ = ["PoseEvidence", "pose_evidence", "NORMAL_AGREEMENT_ANGLE", "FREE_SPACE_DEPTH",
           "RAY_RADIUS", "RAY_NEIGHBOURS", "MIN_INCIDENCE", "motion_support", "Motion",
           "least_supported_motion", "weakest_motion"]


@dataclass(frozen=True)
class PoseEvidence:
    """How a pose fits the target (see the module docstring).

    Attributes
    ----------
    fit : float
        Share of the source points the target could show within a voxel of it, [0, 1]
        (``result.fit``).
    target_fit : float
        Share of the target's points inside the posed source's ball within a voxel of
        the source, [0, 1] (1 when the ball holds none).
    plane_distance : float
        Median point-to-plane distance of the source inliers, in voxels (1 when there is
        no inlier).
    normal_agreement : float
        Share of the inliers whose normals agree, [0, 1] (0 when there is none).
    free_space : float or None
        Share of the source points facing the target's sensor (:data:`MIN_INCIDENCE`)
        that lie in its free space, [0, 1]; None where the target's sensor is unknown.
    rival_fit : float
        Fit of the best distinct pose found (:func:`o3d_spectral.evidence.verification.ambiguity`),
        [0, 1].
    ambiguous : bool
        That pose fits as well as this one.
    rival_self_match : float
        How far the turn between the two poses moves the source off its own surface,
        voxels (0: a symmetry of the source; inf when no rival was found).
    two_views : bool
        The source and the target are both single views of a located sensor, matched
        whole: the fit counts what the target's sensor could see of the source, their
        overlap, which may be small for a right pose.
    motion_support : float
        The inliers' least share of the constraint on a rigid motion, [0, 1]
        (:func:`motion_support`; 1 when too few points have normals, 0 when no target
        point lies near the pose).
    free_motions : tuple of FreeMotion
        The motions that leave the fit unchanged
        (:func:`o3d_spectral.evidence.free_motions.free_motions`), in the frame of
        ``pose``'s target.
    """

    fit: float
    target_fit: float
    plane_distance: float
    normal_agreement: float
    free_space: float | None
    rival_fit: float = 0.0
    ambiguous: bool = False
    rival_self_match: float = float("inf")
    two_views: bool = False
    motion_support: float = 1.0
    free_motions: tuple[FreeMotion, ...] = ()


def pose_evidence(
    source_points: NDArray[np.float64], source_normals: NDArray[np.float64],
    target_points: NDArray[np.float64], target_normals: NDArray[np.float64],
    pose: NDArray[np.float64], voxel_size: float, *, fit: float, rival_fit: float = 0.0,
    ambiguous: bool = False, rival_self_match: float = float("inf"), two_views: bool = False,
    sensor: NDArray[np.float64] | None = None, two_sided: bool = False,
    tree: cKDTree | None = None,
) -> PoseEvidence:
    """The evidence of ``pose`` (see :class:`PoseEvidence`).

    Parameters
    ----------
    source_points, source_normals : ndarray, shape (M, 3)
        The source, one point per voxel (metres), and its unit normals (zero where
        unknown), before ``pose``.
    target_points, target_normals : ndarray, shape (N, 3)
        The target's down-sampled points (metres) and unit normals.
    pose : ndarray, shape (4, 4)
        Source to target.
    voxel_size : float
        Metres; distances are measured in it.
    fit, rival_fit, ambiguous, rival_self_match, two_views
        As :class:`PoseEvidence` holds them (:mod:`o3d_spectral.evidence.verification`).
    sensor : ndarray, shape (3,), or None
        The target's sensor (metres) where the target is a single view whose sensor was
        located; None otherwise (no free-space test, no culling).
    two_sided : bool
        The source was read two-sided (its normals' signs mean nothing): every point
        faces the sensor.
    tree : scipy.spatial.cKDTree, optional
        A KD-tree of ``target_points`` (built here, on the target's points near the pose,
        when None).

    Returns
    -------
    PoseEvidence
    """
    v = float(voxel_size)
    posed, normals, facing = _shown(source_points, source_normals, pose, sensor, two_sided)
    centre = posed.mean(axis=0)
    radius = float(np.sqrt(np.max(np.sum((posed - centre) ** 2, axis=1)))) + 2.0 * v
    near = np.sum((target_points - centre) ** 2, axis=1) <= radius * radius
    near_points, near_normals = target_points[near], target_normals[near]
    shown, shown_normals = posed[facing], normals[facing]
    rival = {"rival_fit": float(rival_fit), "ambiguous": bool(ambiguous),
             "rival_self_match": float(rival_self_match), "two_views": bool(two_views)}
    if len(near_points) == 0:  # no target point near: nothing supports any motion
        return PoseEvidence(float(fit), 1.0, 1.0, 0.0, None if sensor is None else 0.0,
                            **rival, motion_support=0.0)
    found_points, found_normals = target_points, target_normals
    if tree is None:  # the points within a voxel of the source are near it
        tree, found_points, found_normals = cKDTree(near_points), near_points, near_normals
    distance, nearest = tree.query(shown, distance_upper_bound=v)
    inlier = np.isfinite(distance)
    plane, agreement, support = 1.0, 0.0, 1.0
    if inlier.any():
        j = nearest[inlier]
        plane = float(np.median(np.abs(np.einsum(
            "ij,ij->i", shown[inlier] - found_points[j], found_normals[j])))) / v
        cosine = np.abs(np.einsum("ij,ij->i", shown_normals[inlier], found_normals[j]))
        agreement = float(np.mean(cosine > np.cos(np.deg2rad(NORMAL_AGREEMENT_ANGLE))))
    weakest = _weakest_of(shown, shown_normals, inlier)  # no inlier: the floor's share
    if weakest is not None:
        support = weakest.share
    free = free_motions(shown, shown_normals, inlier, found_points, found_normals, tree, v,
                        posed, normals)
    inside = near_points[np.sum((near_points - centre) ** 2, axis=1) <= (radius - v) ** 2]
    target_fit = 1.0
    if len(inside):
        explained, _ = cKDTree(posed).query(inside, distance_upper_bound=v)
        target_fit = float(np.mean(np.isfinite(explained)))
    free_space = None
    if sensor is not None:  # on the points the sensor sees squarely (not at grazing rays)
        rays = sensor - shown
        incidence = np.einsum("ij,ij->i", shown_normals, rays)
        incidence /= np.maximum(np.linalg.norm(rays, axis=1), 1e-12)
        square = np.abs(incidence) > MIN_INCIDENCE if two_sided else incidence > MIN_INCIDENCE
        free_space = _free_space(shown[square], target_points, sensor, v)
    return PoseEvidence(float(fit), target_fit, plane, agreement, free_space, **rival,
                        motion_support=support, free_motions=free)


class Motion(NamedTuple):
    """A small rigid motion about ``centre``: each point ``p`` moves by
    ``rotation x (p - centre) + translation``, and the share of the constraint on it
    that the inliers carry (:func:`least_supported_motion`); ``radius``, the points' RMS
    distance to ``centre`` (metres: a rotation times it is comparable with a
    translation)."""

    share: float
    rotation: NDArray[np.float64]
    translation: NDArray[np.float64]
    centre: NDArray[np.float64]
    radius: float


def least_supported_motion(
    points: NDArray[np.float64], normals: NDArray[np.float64], inlier: NDArray[np.bool_]
) -> Motion:
    """The rigid motion whose constraint the ``inlier`` points carry the least share of.

    A point ``p`` (metres) with unit normal ``n`` resists the small motion of rotation
    ``w`` about the points' centroid ``c`` and translation ``u`` by
    ``r = ((p - c) / L x n) . w + n . u`` (point-to-plane ICP's linearised residual;
    ``L``, the points' RMS distance to ``c``, makes ``w`` a length). With ``A`` the sum of
    ``r``'s squared coefficients over every point and ``B`` over the inliers, both
    6 x 6, the share along a motion ``x`` is ``x^T B x / x^T A x``; the least is the
    smallest generalised eigenvalue of ``(B, A)``, each plus
    :data:`~o3d_spectral.evidence.free_motions.SUPPORT_FLOOR` times
    ``trace(A) / 6`` on its diagonal, and its eigenvector the motion (Gelfand et al.'s
    geometric stability, 2003).

    Parameters
    ----------
    points, normals : ndarray, shape (M, 3)
        Points (metres) and their unit normals, M >= 1.
    inlier : ndarray of bool, shape (M,)

    Returns
    -------
    Motion
        The share in [0, 1]; the rotation (radians per unit of the motion) and the
        translation of ``c`` (metres), of unit length together once the rotation is
        scaled by ``L``.
    """
    rows, centre, scale = constraint_rows(points, normals)
    every, inliers = rows.T @ rows, rows[inlier].T @ rows[inlier]
    floor = support_floor(every) * np.eye(6)
    values, vectors = scipy.linalg.eigh(inliers + floor, every + floor)
    motion = vectors[:, 0] / max(float(np.linalg.norm(vectors[:, 0])), 1e-300)
    return Motion(float(min(max(values[0], 0.0), 1.0)), motion[:3] / scale, motion[3:], centre,
                  scale)


def motion_support(
    points: NDArray[np.float64], normals: NDArray[np.float64], inlier: NDArray[np.bool_]
) -> float:
    """The least share, over the rigid motions, of the points' constraint on a motion that
    the ``inlier`` points carry, in [0, 1]: :func:`least_supported_motion`'s share, for
    the same arguments."""
    return least_supported_motion(points, normals, inlier).share


def weakest_motion(
    source_points: NDArray[np.float64], source_normals: NDArray[np.float64],
    pose: NDArray[np.float64], voxel_size: float, tree: cKDTree, *,
    sensor: NDArray[np.float64] | None = None, two_sided: bool = False,
) -> Motion | None:
    """The motion the inliers of ``pose`` resist least, measured as
    :func:`pose_evidence` measures the motion support (the source points the target's
    sensor could see, inliers within a voxel of the target); None where too few points
    have normals.

    Parameters
    ----------
    source_points, source_normals, pose, voxel_size, sensor, two_sided
        As for :func:`pose_evidence`.
    tree : scipy.spatial.cKDTree
        A KD-tree of the target's points.

    Returns
    -------
    Motion or None
        In the target's frame.
    """
    posed, normals, facing = _shown(source_points, source_normals, pose, sensor, two_sided)
    shown, shown_normals = posed[facing], normals[facing]
    distance, _ = tree.query(shown, distance_upper_bound=float(voxel_size))
    return _weakest_of(shown, shown_normals, np.isfinite(distance))


def _weakest_of(
    points: NDArray[np.float64], normals: NDArray[np.float64], inlier: NDArray[np.bool_]
) -> Motion | None:
    """:func:`least_supported_motion` of the points that have a normal (zero rows have
    none); None where fewer than :data:`MIN_POINTS` do."""
    has_normal = known(normals)
    if has_normal.sum() < MIN_POINTS:
        return None
    return least_supported_motion(points[has_normal], normals[has_normal], inlier[has_normal])


def _shown(
    source_points: NDArray[np.float64], source_normals: NDArray[np.float64],
    pose: NDArray[np.float64], sensor: NDArray[np.float64] | None, two_sided: bool,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
    """The source points and normals posed, and which of them face ``sensor`` (what it
    could see of the source; all of them where it is None, the source is two-sided, or
    fewer than :data:`MIN_POINTS` would)."""
    R, t = pose[:3, :3], pose[:3, 3]
    posed, normals = source_points @ R.T + t, source_normals @ R.T
    facing = np.ones(len(posed), dtype=bool)
    if sensor is not None and not two_sided:
        facing = np.einsum("ij,ij->i", normals, sensor - posed) > 0.0
        if facing.sum() < MIN_POINTS:
            facing[:] = True
    return posed, normals, facing


def _free_space(
    points: NDArray[np.float64], target_points: NDArray[np.float64],
    sensor: NDArray[np.float64], voxel_size: float,
) -> float:
    """Share of ``points`` (K, 3, metres) with a target point on their ray from
    ``sensor`` (within :data:`RAY_RADIUS` voxels) whose nearest such point lies over
    :data:`FREE_SPACE_DEPTH` voxels behind them."""
    if len(points) == 0:
        return 0.0
    rays = points - sensor
    depth = np.linalg.norm(rays, axis=1)
    directions = rays / np.maximum(depth, 1e-12)[:, None]
    seen = target_points - sensor
    seen_depth = np.linalg.norm(seen, axis=1)
    seen_directions = seen / np.maximum(seen_depth, 1e-12)[:, None]
    width = RAY_RADIUS * voxel_size / np.maximum(depth, 1e-12)  # chord on the unit sphere
    axis = directions.mean(axis=0)
    axis /= max(float(np.linalg.norm(axis)), 1e-12)
    cone = float(np.max(np.linalg.norm(directions - axis, axis=1))) + float(width.max())
    in_cone = np.linalg.norm(seen_directions - axis, axis=1) <= cone  # the source's rays only
    if not in_cone.any():
        return 0.0
    seen_depth, seen_directions = seen_depth[in_cone], seen_directions[in_cone]
    gap, index = cKDTree(seen_directions).query(directions, k=RAY_NEIGHBOURS,
                                                 distance_upper_bound=float(width.max()))
    on = gap <= width[:, None]  # within each ray's own width (inf where none)
    candidate = np.where(on, seen_depth[np.minimum(index, len(seen_depth) - 1)], np.inf)
    nearest = candidate.min(axis=1)
    on_ray = on.any(axis=1)
    behind = on_ray & (nearest > depth + FREE_SPACE_DEPTH * voxel_size)
    return float(np.mean(behind))
