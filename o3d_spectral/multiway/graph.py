"""The pose-graph stages of :func:`o3d_spectral.registration_multiway`, on pairwise
results made by any method: selection, spanning tree, optimisation, refinement.

:func:`poses_from_pairs` runs them on :class:`o3d_spectral.PairwiseRecord` of each
registered pair; ``docs/multiway.md`` describes each stage.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence

import numpy as np
import open3d as o3d
from numpy.typing import NDArray

from ..common.checks import check_instance, check_voxel_size
from ..common.parallel import one_open3d_thread, thread_map
from ..evidence.free_motions import leaves_motion_free
from ..io.cloud import CloudArrays, as_arrays
from ..io.units import MAX_EXTENT_RATIO, span
from ..refinement.icp import point_to_plane_icp
from .constants import FINE_CELL, FINE_DISTANCE, FREE_SPACE_MARGIN, NORMAL_VOXELS
from .options import MultiwayOption, MultiwayResult, PairwiseRecord
from .tree import Joinable, chained, maximum_spanning_tree
from .visibility import checked_cameras, free_space_test

__all__ = ["poses_from_pairs", "checked_clouds", "selected", "confident", "tree_weight"]

reg = o3d.pipelines.registration
#: An edge of a pose graph: (source cloud, target cloud, source-to-target transformation,
#: information matrix (6, 6), uncertain).
Edge = tuple[int, int, NDArray[np.float64], NDArray[np.float64], bool]


def poses_from_pairs(
    clouds: Sequence[object], voxel_size: float, records: Sequence[PairwiseRecord], *,
    option: MultiwayOption | None = None,
    camera_locations: Sequence[object | None] | None = None,
) -> MultiwayResult:
    """Steps 2-5 of :func:`registration_multiway` on pairwise results made by any method.

    Open3D's own parallel loops run on one thread meanwhile
    (:func:`o3d_spectral.common.parallel.one_open3d_thread`): the result repeats to the bit,
    whatever ``option.workers``.

    Parameters
    ----------
    clouds, voxel_size, option, camera_locations
        As :func:`o3d_spectral.registration_multiway`.
    records : sequence of PairwiseRecord
        One per registered pair (``kept`` and ``uncertain`` are set here from ``fit``,
        ``fitness``, ``rival_fit`` and ``confidence``; a method without a rival may give
        0, one without a confidence None).

    Returns
    -------
    MultiwayResult

    Raises
    ------
    ValueError, TypeError
        As :func:`registration_multiway`, and for a record whose clouds are not
        ``0 <= source < target < len(clouds)``.
    """
    with one_open3d_thread():
        return _poses_from_pairs(clouds, voxel_size, records, option, camera_locations)


def _poses_from_pairs(
    clouds: Sequence[object], voxel_size: float, records: Sequence[PairwiseRecord],
    option: MultiwayOption | None, camera_locations: Sequence[object | None] | None,
) -> MultiwayResult:
    """:func:`poses_from_pairs` (its Open3D threads limited by the caller)."""
    start = time.perf_counter()
    voxel_size = check_voxel_size(voxel_size)
    check_instance("option", option, MultiwayOption)
    option = option or MultiwayOption()
    arrays = checked_clouds(clouds)
    cameras = checked_cameras(camera_locations, len(arrays))
    n = len(arrays)
    for k, r in enumerate(records):
        if not 0 <= r.source < r.target < n:
            raise ValueError(f"records[{k}] pairs clouds {r.source} and {r.target}: "
                             f"need 0 <= source < target < {n} (the number of clouds)")
    downs = thread_map(lambda a: _down_sampled(a, voxel_size), arrays, option.workers)
    distance = option.distance_voxels * voxel_size
    centres = [a.points.mean(axis=0) for a in arrays]
    free = [leaves_motion_free(np.asarray(d.points), np.asarray(d.normals)) for d in downs]
    records = [dataclasses.replace(selected(r, option),
                                   determined=not (free[r.source] or free[r.target]))
               for r in records]
    joinable = free_space_test([a.points for a in arrays], [np.asarray(d.points) for d in downs],
                               cameras, FREE_SPACE_MARGIN * voxel_size, voxel_size,
                               option.max_free_space)
    records, tree, poses = _placed(n, records, centres, voxel_size, option, joinable)
    kept = [r for r in records if r.kept]
    nodes = tuple(k for k in range(n) if poses[k] is not None)
    edges = [(r.source, r.target, r.transformation,
              _information(downs, r.source, r.target, distance, r.transformation), r.uncertain)
             for r in kept if r.source in nodes]
    graph = _optimised(nodes, poses, edges, distance, option.edge_prune_threshold)
    if option.refine and len(nodes) > 1:
        poses = _node_poses(graph, nodes, n)
        certain = {(r.source, r.target) for r in kept if not r.uncertain}
        fines = thread_map(lambda a: _fine(a, voxel_size), arrays, option.workers)
        trusted = {(r.source, r.target): r.transformation for r in kept
                   if (r.source, r.target) in set(tree) | certain}
        edges = _refined_edges(downs, fines, centres, poses,
                               [(r.source, r.target) for r in records], trusted, certain,
                               voxel_size, option)
        graph = _optimised(nodes, poses, edges, distance, option.edge_prune_threshold)
    trusted = _reached(n, [(r.source, r.target) for r in kept if confident(r, option)])
    return MultiwayResult(
        poses=tuple(_node_poses(graph, nodes, n)), pose_graph=graph, nodes=nodes,
        pairs=tuple(records), unconnected=tuple(k for k in range(n) if k not in nodes),
        run_time=time.perf_counter() - start,
        doubtful=tuple(k for k in nodes if k not in trusted),
    )


def _reached(n: int, links: list[tuple[int, int]]) -> set[int]:
    """The clouds a chain of ``links`` (pairs of cloud indices) joins to cloud 0: those
    :func:`o3d_spectral.multiway.tree.chained` places along them."""
    placed = chained(n, links, dict.fromkeys(links, np.eye(4)))
    return {k for k, pose in enumerate(placed) if pose is not None}


def checked_clouds(clouds: Sequence[object]) -> list[CloudArrays]:
    """The clouds as checked arrays (copies); fewer than two, or extents differing by
    :data:`o3d_spectral.io.units.MAX_EXTENT_RATIO` or more, refused naming ``clouds``."""
    if isinstance(clouds, np.ndarray | o3d.geometry.PointCloud | o3d.t.geometry.PointCloud):
        raise TypeError("clouds must be a sequence of clouds (a list), got one cloud")
    try:
        count = len(clouds)
    except TypeError:
        raise TypeError(f"clouds must be a sequence of clouds, got "
                        f"{type(clouds).__qualname__}") from None
    if count < 2:
        raise ValueError(f"clouds must hold at least two clouds to register, got {count}")
    arrays = [as_arrays(cloud, f"clouds[{k}]") for k, cloud in enumerate(clouds)]
    spans = [span(a.points) for a in arrays]
    small, large = int(np.argmin(spans)), int(np.argmax(spans))
    if spans[small] > 0.0 and spans[large] >= MAX_EXTENT_RATIO * spans[small]:
        raise ValueError(
            f"clouds[{large}] spans {spans[large]:.3g} m and clouds[{small}] "
            f"{spans[small]:.3g} m ({spans[large] / spans[small]:.0f}x): are the clouds in "
            f"the same units (metres)? Extents differing by {MAX_EXTENT_RATIO:.0f}x or "
            "more cannot be registered at one voxel size")
    return arrays


def _down_sampled(arrays: CloudArrays, voxel_size: float) -> o3d.geometry.PointCloud:
    """The cloud down-sampled to one point per voxel, its normals estimated over
    :data:`NORMAL_VOXELS` voxels (the information matrices' and the first ICP's input)."""
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(arrays.points))
    cloud = cloud.voxel_down_sample(voxel_size)
    cloud.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(NORMAL_VOXELS * voxel_size, 30))
    return cloud


def selected(record: PairwiseRecord, option: MultiwayOption) -> PairwiseRecord:
    """The record with ``kept`` and ``uncertain`` set by ``option``'s thresholds."""
    lead = record.fit - record.rival_fit
    kept = record.fit >= option.min_fit and record.fitness >= option.min_fitness
    certain = (kept and record.fit >= option.certain_fit and lead >= option.certain_margin
               and confident(record, option))
    return dataclasses.replace(record, kept=kept, uncertain=not certain)


def confident(record: PairwiseRecord, option: MultiwayOption) -> bool:
    """Whether the pairwise call did not warn about the record's pose: its confidence
    is at least ``option.min_confidence``, or it has none."""
    return record.confidence is None or record.confidence >= option.min_confidence


def tree_weight(record: PairwiseRecord, option: MultiwayOption) -> float:
    """A kept pair's weight in the maximum spanning tree: its ``fit``, less 1 when it
    does not lead its ``rival_fit`` by ``option.rival_margin`` (a pair of views of a
    symmetric object has a rival as good, its symmetric pose, and may still be right),
    less 2 when one of its clouds leaves a motion free (``record.determined``: the pose
    is one of a continuum, a weaker claim than one of two rivals), and less 4 when the
    pairwise call warned about it (:func:`confident`). Each kind of pair joins the tree
    only where none of the kinds before it does."""
    led = record.fit - record.rival_fit >= option.rival_margin
    return (record.fit - (0.0 if led else 1.0) - (0.0 if record.determined else 2.0)
            - (0.0 if confident(record, option) else 4.0))


def _placed(
    n: int, records: list[PairwiseRecord], centres: list[NDArray[np.float64]],
    voxel_size: float, option: MultiwayOption, joinable: Joinable | None,
) -> tuple[list[PairwiseRecord], list[tuple[int, int]], list[NDArray[np.float64] | None]]:
    """The tree of the kept pairs, the poses chained along it, and the records with
    ``kept`` cleared for the pairs that disagree with those poses (:func:`_fits_tree`).

    A cloud placed by weak tree edges alone (``fit`` under ``option.certain_fit``) while
    its other kept pairs all disagree with it is contradicted: a cloud of another object
    that two scans each match somewhere. Its pairs are dropped and the tree built again,
    until no cloud is contradicted. A disagreeing pair contradicts only where it offers
    the cloud another place (:func:`_elsewhere`): not when its other cloud is unplaced,
    nor when ``joinable`` refuses that place against a placed cloud (its points in space
    a camera saw empty)."""
    while True:
        kept = [r for r in records if r.kept]
        transformations = {(r.source, r.target): r.transformation for r in kept}
        tree = maximum_spanning_tree(n, [(r.source, r.target, tree_weight(r, option))
                                         for r in kept], transformations, joinable)
        poses = chained(n, tree, transformations)
        agree = [r.kept and _fits_tree(r, tree, poses, centres, voxel_size, option)
                 for r in records]
        doubted = set()
        for k in range(1, n):
            mine = [(r, a) for r, a in zip(records, agree, strict=True)
                    if r.kept and k in (r.source, r.target)]
            branches = [r for r, _ in mine if (r.source, r.target) in tree]
            # Its other pairs that say something: agree with the tree, or offer elsewhere.
            said = [a for r, a in mine if r not in branches
                    and (a or _elsewhere(r, k, poses, joinable))]
            if said and not any(said) and all(r.fit < option.certain_fit for r in branches):
                doubted.add(k)
        if not doubted:
            return ([dataclasses.replace(r, kept=a) for r, a in zip(records, agree,
                                                                    strict=True)],
                    tree, poses)
        records = [dataclasses.replace(r, kept=r.kept and not {r.source, r.target} & doubted)
                   for r in records]


def _elsewhere(
    record: PairwiseRecord, k: int, poses: list[NDArray[np.float64] | None],
    joinable: Joinable | None,
) -> bool:
    """Whether ``record`` offers cloud ``k`` another place in the model: its other cloud is
    placed, and the pose it gives ``k`` against it is one ``joinable`` allows against
    every other placed cloud (any, without ``joinable``)."""
    other = record.target if record.source == k else record.source
    if poses[other] is None:
        return False
    if joinable is None:
        return True
    pose = poses[other] @ (record.transformation if other == record.target
                           else np.linalg.inv(record.transformation))
    return all(joinable(k, q, np.linalg.inv(placed) @ pose)
               for q, placed in enumerate(poses) if q != k and placed is not None)


def _agree(
    one: NDArray[np.float64], other: NDArray[np.float64], centre: NDArray[np.float64],
    voxel_size: float, option: MultiwayOption,
) -> bool:
    """Whether two transformations (4, 4) are within ``option.cycle_degrees`` of each
    other and move ``centre`` (3,) to within ``option.cycle_voxels`` voxels."""
    cosine = (np.trace(one[:3, :3].T @ other[:3, :3]) - 1.0) / 2.0
    angle = np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0)))
    shift = np.linalg.norm((one[:3, :3] - other[:3, :3]) @ centre + one[:3, 3] - other[:3, 3])
    return bool(angle <= option.cycle_degrees and shift <= option.cycle_voxels * voxel_size)


def _fits_tree(
    record: PairwiseRecord, tree: list[tuple[int, int]],
    poses: list[NDArray[np.float64] | None], centres: list[NDArray[np.float64]],
    voxel_size: float, option: MultiwayOption,
) -> bool:
    """Whether a kept pair is an edge of the tree or agrees with the poses chained along
    it (``option.cycle_degrees`` and ``cycle_voxels``). Between views of a symmetric
    object each pair may be right up to a different element of its symmetry group: the
    pairs that agree with the tree make one consistent model, where optimising them all
    would average incompatible ones."""
    i, j = record.source, record.target
    if (i, j) in tree or poses[i] is None or poses[j] is None:
        return (i, j) in tree
    return _agree(record.transformation, np.linalg.inv(poses[j]) @ poses[i], centres[i],
                  voxel_size, option)


def _information(
    downs: list[o3d.geometry.PointCloud], i: int, j: int, distance: float,
    transformation: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Open3D's information matrix (6, 6) of the edge from cloud i to cloud j."""
    return np.asarray(reg.get_information_matrix_from_point_clouds(
        downs[i], downs[j], distance, transformation))


def _optimised(
    nodes: tuple[int, ...], poses: list[NDArray[np.float64] | None], edges: list[Edge],
    distance: float, prune: float,
) -> o3d.pipelines.registration.PoseGraph:
    """The pose graph of ``nodes`` (initial poses ``poses``) and ``edges``, optimised by
    Open3D's Levenberg-Marquardt with its line process (reference node 0)."""
    graph = reg.PoseGraph()
    index = {cloud: k for k, cloud in enumerate(nodes)}
    for cloud in nodes:
        graph.nodes.append(reg.PoseGraphNode(np.array(poses[cloud])))
    for i, j, transformation, information, uncertain in edges:
        graph.edges.append(reg.PoseGraphEdge(index[i], index[j], transformation,
                                             information, uncertain=uncertain))
    if len(nodes) > 1:
        option = reg.GlobalOptimizationOption(max_correspondence_distance=distance,
                                              edge_prune_threshold=prune, reference_node=0)
        # Uncertain edges are meant: Open3D's warning that the certain ones do not
        # connect the graph is left out.
        with o3d.utility.VerbosityContextManager(o3d.utility.VerbosityLevel.Error):
            reg.global_optimization(graph, reg.GlobalOptimizationLevenbergMarquardt(),
                                    reg.GlobalOptimizationConvergenceCriteria(), option)
    return graph


def _node_poses(
    graph: o3d.pipelines.registration.PoseGraph, nodes: tuple[int, ...], n: int
) -> list[NDArray[np.float64] | None]:
    """Each cloud's pose from ``graph``, in the first node's frame, its rotation made
    exactly orthonormal; None for a cloud that is not a node."""
    poses: list[NDArray[np.float64] | None] = [None] * n
    poses[nodes[0]] = np.eye(4)
    first = np.linalg.inv(np.asarray(graph.nodes[0].pose))
    for k, cloud in enumerate(nodes[1:], start=1):
        pose = first @ np.asarray(graph.nodes[k].pose, dtype=np.float64)
        u, _, vt = np.linalg.svd(pose[:3, :3])
        pose[:3, :3] = u @ np.diag([1.0, 1.0, np.linalg.det(u @ vt)]) @ vt
        pose[3] = (0.0, 0.0, 0.0, 1.0)
        poses[cloud] = pose
    return poses


def _fine(arrays: CloudArrays, voxel_size: float) -> o3d.geometry.PointCloud:
    """The cloud down-sampled to :data:`FINE_CELL` voxels, its normals estimated over
    one voxel: the resolution the registration's own polish reads the surface at."""
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(arrays.points))
    cloud = cloud.voxel_down_sample(FINE_CELL * voxel_size)
    cloud.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(voxel_size, 30))
    return cloud


def _refined_edges(
    downs: list[o3d.geometry.PointCloud], fines: list[o3d.geometry.PointCloud],
    centres: list[NDArray[np.float64]], poses: list[NDArray[np.float64] | None],
    pairs: list[tuple[int, int]], trusted: dict[tuple[int, int], NDArray[np.float64]],
    certain: set[tuple[int, int]], voxel_size: float, option: MultiwayOption,
) -> list[Edge]:
    """Each pair of placed clouds registered again from the optimised ``poses``: a
    point-to-plane ICP on the voxel down-samples at ``option.distance_voxels``, then one
    on the fine clouds at :data:`FINE_DISTANCE` voxels. Kept when the clouds overlap
    there (the first ICP's fitness at least ``option.refine_min_fitness``) and the ICP
    stayed near the poses (``option.cycle_degrees`` and ``cycle_voxels``: between views
    that share little, it can slide along the surface); a ``trusted`` pair (the tree's
    and the certain edges) is always kept, its pairwise transformation standing in for
    an ICP that overlapped too little or slid. Uncertain unless ``certain``."""
    placed = [(i, j) for i, j in pairs if poses[i] is not None and poses[j] is not None]
    distance = option.distance_voxels * voxel_size

    def refined(pair: tuple[int, int]) -> Edge | None:
        i, j = pair
        init = np.linalg.inv(poses[j]) @ poses[i]
        coarse = point_to_plane_icp(downs[i], downs[j], distance, init)
        fitness = reg.evaluate_registration(downs[i], downs[j], distance, coarse).fitness
        transformation = point_to_plane_icp(fines[i], fines[j], FINE_DISTANCE * voxel_size,
                                            coarse)
        if fitness < option.refine_min_fitness or not _agree(
                transformation, init, centres[i], voxel_size, option):
            if pair not in trusted:
                return None
            transformation = trusted[pair]
        information = _information(downs, i, j, distance, transformation)
        return i, j, transformation, information, pair not in certain

    return [e for e in thread_map(refined, placed, option.workers) if e is not None]
