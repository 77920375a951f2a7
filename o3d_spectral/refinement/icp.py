"""The point-to-plane ICP polish of a registration's final pose.

The law's pose is within about a degree and a couple of millimetres; Open3D's
global-registration tutorial polishes FPFH-RANSAC's pose with a point-to-plane ICP whose
correspondences reach 0.4 voxel, and so does :func:`refine` (with an optional wider first
pass, and a guard against an ICP that slides off the surface). The harness' FPFH
baselines use :func:`point_to_plane_refinement`, the tutorial's step alone.
"""

from __future__ import annotations

import numpy as np
import open3d as o3d
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from ..common.parallel import one_open3d_thread
from ..io.cloud import extent
from ..io.density import first_per_cell
from ..io.rows import in_ball, lengths
from ..options import RefinementOption
from .constants import GUARD_SHARE, MAX_POLISH_POINTS, REACH, RECUTS, TUTORIAL_DISTANCE

__all__ = [
    "point_to_plane_icp", "point_to_plane_refinement", "refine", "near_pose", "GUARD_SHARE",
    "polish_within_reach", "convergence", "REACH", "RECUTS",
    "with_normals", "thinned", "evenly_spread", "MAX_POLISH_POINTS",
]


def thinned(cloud: o3d.geometry.PointCloud, cell: float) -> o3d.geometry.PointCloud:
    """``cloud`` (normals kept) with its first point in each cube of ``cell`` metres
    (:func:`o3d_spectral.io.density.first_per_cell`); ``cloud`` itself where no two points
    share a cell."""
    keep = first_per_cell(np.asarray(cloud.points), cell)
    return cloud if len(keep) == len(cloud.points) else cloud.select_by_index(keep)


def evenly_spread(cloud: o3d.geometry.PointCloud, count: int) -> o3d.geometry.PointCloud:
    """``cloud`` itself, or where it holds more than ``count`` points, ``count`` of them
    (normals kept) evenly spread over its order, its first and last included."""
    total = len(cloud.points)
    if total <= count:
        return cloud
    return cloud.select_by_index(np.linspace(0, total - 1, count).astype(np.int64))


def near_pose(
    target: o3d.geometry.PointCloud,
    source_points: NDArray[np.float64],
    transformation: NDArray[np.float64],
    margin: float,
) -> tuple[o3d.geometry.PointCloud, NDArray[np.int64]]:
    """The target's points within ``margin`` (metres) of the ball holding the source
    points (N, 3) at ``transformation`` (4, 4), and their indices in ``target``.

    A correspondence search up to ``margin`` from the posed source finds exactly the same
    points in this crop as in the whole target, and a KD-tree of a scene's neighbourhood
    of the object is much cheaper to build than one of the whole scene.
    """
    centroid, reach = extent(source_points)
    reach += margin
    centre = transformation[:3, :3] @ centroid + transformation[:3, 3]
    keep = np.flatnonzero(in_ball(np.asarray(target.points), centre, reach))
    return target.select_by_index(keep), keep


def point_to_plane_icp(
    source: o3d.geometry.PointCloud,
    target: o3d.geometry.PointCloud,
    max_distance: float,
    init: ArrayLike,
    cut_from: NDArray[np.float64] | None = None,
) -> NDArray[np.float64]:
    """Open3D's point-to-plane ICP from ``init`` (4, 4), correspondences up to
    ``max_distance`` metres; returns the 4x4 source-to-target transformation.

    ``target`` must have normals. The ICP runs in the target's frame moved to where
    ``init`` puts the source's centroid, and its result is expressed in the caller's
    frame again. Each of Open3D's steps solves for a small rotation about the frame's
    origin, linearised; applied exactly it leaves an error of about ``a^2 d / 2`` at a
    point ``d`` from that origin (a 2.6 degree first step at 50 m: 5 cm), which far from
    the origin throws the source out of the correspondence distance after one step.
    About the source's centroid the error is that of the object's own size, at any
    distance. Open3D's loops run on one thread
    (:func:`o3d_spectral.common.parallel.one_open3d_thread`):
    a result must repeat exactly; several ICPs may run side by side on the caller's
    threads, as Open3D's ICP releases the GIL.

    ``cut_from`` (M, 3): the points of the cloud ``source`` was cut from (the ICP then
    runs about their centroid, and its convergence test, on changes of the share of
    points that correspond, counts that share out of their M), so that the ICP of a cut
    holding every point that can correspond is the ICP of the whole cloud
    (:func:`polish_within_reach`).
    """
    init = np.asarray(init, dtype=np.float64)
    points = np.asarray(source.points) if cut_from is None else cut_from
    centre = init[:3, :3] @ points.mean(axis=0) + init[:3, 3] if len(points) else np.zeros(3)
    moved = o3d.geometry.PointCloud(target).translate(-centre)  # a copy; normals unchanged
    to_centre = np.eye(4)
    to_centre[:3, 3] = -centre
    with one_open3d_thread():
        result = o3d.pipelines.registration.registration_icp(
            source,
            moved,
            max_distance,
            to_centre @ init,
            o3d.pipelines.registration.TransformationEstimationPointToPlane(),
            convergence(len(points), len(source.points)),
        )
    transformation = np.array(result.transformation)
    transformation[:3, 3] += centre
    return transformation


def convergence(whole: int, cut: int) -> o3d.pipelines.registration.ICPConvergenceCriteria:
    """Open3D's default ICP convergence (30 iterations; changes of fitness and RMSE under
    1e-6) for a cut of ``cut`` points out of ``whole``: Open3D reads the fitness as the
    share of the source that corresponds, so the fitness threshold is scaled by
    ``whole / cut`` to stop where the whole cloud's ICP stops."""
    criteria = o3d.pipelines.registration.ICPConvergenceCriteria()
    if cut and cut != whole:
        criteria.relative_fitness *= whole / cut
    return criteria


def point_to_plane_refinement(
    source: o3d.geometry.PointCloud,
    target: o3d.geometry.PointCloud,
    voxel_size: float,
    init: ArrayLike,
    distance: float = TUTORIAL_DISTANCE,
) -> NDArray[np.float64]:
    """Open3D's point-to-plane ICP from ``init`` (4, 4), correspondences up to
    ``distance`` voxels of ``voxel_size`` (metres): the refinement of Open3D's
    global-registration tutorial (0.4 voxel). ``target`` must have normals."""
    return point_to_plane_icp(source, target, distance * voxel_size, init)


def refine(
    source: o3d.geometry.PointCloud,
    target: o3d.geometry.PointCloud,
    voxel_size: float,
    init: NDArray[np.float64],
    option: RefinementOption,
) -> NDArray[np.float64]:
    """Polish ``init`` (4, 4): :func:`point_to_plane_refinement` at ``option.distance``,
    from ``init`` itself or, with ``option.wide_distance``, from where a first ICP with
    correspondences up to that many voxels takes it, whichever fits better (Open3D's
    fitness at ``option.distance``, the first of equals; measured on one KD-tree of the
    target for every pose, where ``evaluate_registration`` would build one per pose: 8 ms
    each on the 44k points of a scene about an object).

    The two starts are polished and compared on the source down-sampled to one point per
    voxel, and only the better is polished again on the whole source: the whole source's
    ICP is most of the cost (a 40k-point dragon scan against one 72 degrees away, which
    shares a fifth of it: 0.2-0.6 s, its 30 iterations spent). Polishing both starts on
    the whole source takes twice as long for no better result. A source of over
    :data:`MAX_POLISH_POINTS` points is polished on that many of them, evenly spread
    (:func:`evenly_spread`): a room's fragment of 200k points at 5 cm gains nothing more
    from the rest.

    ``init`` itself when the kept result has at most ``GUARD_SHARE`` of the inliers of
    ``init`` at ``option.distance``: from a wrong pose with few correspondences on a thin
    or flat part, the ICP's normal equations are nearly singular and it can leave the
    surface altogether (a scissors view sent 90 m away), which no refinement should do.
    ``target`` must have normals. With ``option.cell``, both clouds are read one point per
    cube of that many voxels (:func:`thinned`) throughout.
    """
    if option.cell is not None:  # the polish's resolution
        source, target = (thinned(c, option.cell * voxel_size) for c in (source, target))
    sparse = source.voxel_down_sample(voxel_size)  # one point per voxel
    points, tree = np.asarray(sparse.points), cKDTree(np.asarray(target.points))

    def fitness(transformation: NDArray[np.float64]) -> float:  # Open3D's, on one tree
        posed = points @ transformation[:3, :3].T + transformation[:3, 3]
        distances, _ = tree.query(posed, distance_upper_bound=option.distance * voxel_size)
        return float(np.count_nonzero(np.isfinite(distances))) / max(len(points), 1)

    start = init  # with nothing to compare, the whole source is polished from init
    if option.wide_distance is not None:
        plain = point_to_plane_refinement(sparse, target, voxel_size, init, option.distance)
        wide = point_to_plane_icp(sparse, target, option.wide_distance * voxel_size, init)
        widened = point_to_plane_refinement(sparse, target, voxel_size, wide, option.distance)
        start = widened if fitness(widened) > fitness(plain) else plain
    refined = polish_within_reach(evenly_spread(source, MAX_POLISH_POINTS), target, tree,
                                  option.distance * voxel_size, start)
    return init if fitness(refined) <= GUARD_SHARE * fitness(init) else refined


def polish_within_reach(
    source: o3d.geometry.PointCloud,
    target: o3d.geometry.PointCloud,
    tree: cKDTree,
    max_distance: float,
    init: NDArray[np.float64],
) -> NDArray[np.float64]:
    """:func:`point_to_plane_icp` of ``source`` from ``init`` (4, 4), run on the source's
    points within ``(1 + REACH) * max_distance`` (metres) of the target there (``tree``,
    a KD-tree of the target's points): the whole source's ICP, at the cost of the points
    that can correspond.

    Between two scans that share a fifth of their surface, four fifths of the source
    never find a point of the target within ``max_distance``, and Open3D's ICP searches
    for one at each of its 30 iterations. A point left out could only come to correspond
    if the ICP moved it by more than :data:`REACH` times ``max_distance``: the cut is
    checked once the ICP has run. Where the pose moved a point left out that far (a pose
    sliding from a start some degrees off), the source is cut again about the pose
    reached and the ICP resumes from there, up to :data:`RECUTS` cuts, then on the whole
    source. The result is the whole source's ICP started from the pose the last cut was
    made at (``init`` when the first cut holds): that ICP finds exactly the cut's
    correspondences at every step. The ICP runs about the whole source's centroid and
    stops where the whole source's would (:func:`convergence`).
    """
    points = np.asarray(source.points)
    reach = REACH * max_distance
    pose = init
    for _ in range(RECUTS):
        posed = points @ pose[:3, :3].T + pose[:3, 3]
        distances, _ = tree.query(posed, distance_upper_bound=max_distance + reach)
        near = np.isfinite(distances)
        if near.all():
            return point_to_plane_icp(source, target, max_distance, pose)
        cut = source.select_by_index(np.flatnonzero(near))
        polished = point_to_plane_icp(cut, target, max_distance, pose, cut_from=points)
        out = points[~near]
        moved = out @ (polished[:3, :3] - pose[:3, :3]).T + (polished[:3, 3] - pose[:3, 3])
        if lengths(moved).max() < reach:
            return polished
        pose = polished
    return point_to_plane_icp(source, target, max_distance, pose)


def with_normals(
    target: o3d.geometry.PointCloud, points: NDArray[np.float64], normals: NDArray[np.float64]
) -> o3d.geometry.PointCloud:
    """``target``, or, when it has no normals, a cloud of ``points`` (N, 3, metres) with
    ``normals`` (N, 3): the fixed cloud's down-sampled points and the normals estimated
    for it (:attr:`o3d_spectral.SpectralStepper.target_normal_points`, ``target_normals``)."""
    if target.has_normals():
        return target
    fixed = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    fixed.normals = o3d.utility.Vector3dVector(normals)
    return fixed
