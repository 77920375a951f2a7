"""Many clouds of one object or scene, in any frames, registered into one model.

:func:`registration_multiway` registers pairs of the clouds with
:func:`o3d_spectral.registration_spectral_global` (no initial pose needed), keeps the pairs
whose result clearly fits, places every cloud by a maximum spanning tree of those pairs
weighted by their ``fit``, and optimises the poses over the kept pairs that agree with
the tree by Open3D's pose graph (Levenberg-Marquardt with a line process that prunes
wrong edges). An optional refinement registers again, by point-to-plane ICP from the
optimised poses, every pair that overlaps there, and optimises that graph.
``docs/multiway.md`` describes the steps and their measure.
"""

from __future__ import annotations

import contextlib
import dataclasses
import itertools
import logging
import threading
import time
from collections.abc import Iterator, Sequence

import numpy as np

from ..common.checks import check_instance, check_voxel_size
from ..common.parallel import thread_map
from ..evidence import diagnostics
from ..io.cloud import CloudArrays
from ..law.prepared import PreparedSource, prepare
from ..law.prepared_target import PreparedTarget, prepare_target
from ..registration import registration_spectral_global
from .graph import checked_clouds, poses_from_pairs, selected
from .options import MultiwayOption, MultiwayResult, PairwiseRecord
from .tree import maximum_spanning_tree
from .visibility import checked_cameras

__all__ = ["registration_multiway", "poses_from_pairs", "pair_list", "maximum_spanning_tree",
           "MultiwayOption", "MultiwayResult", "PairwiseRecord"]

log = logging.getLogger(__name__)


def registration_multiway(
    clouds: Sequence[object], voxel_size: float, *, option: MultiwayOption | None = None,
    camera_locations: Sequence[object | None] | None = None,
) -> MultiwayResult:
    """Register ``clouds`` (in any frames, no initial poses) into the first one's frame.

    1. **pairs**: every pair of clouds up to ``option.max_all_pairs`` clouds, else each
       with its ``option.neighbours`` successors, registered by
       :func:`o3d_spectral.registration_spectral_global` (each cloud prepared once as a
       source and once as a target) on ``option.workers`` threads;
    2. **selection**: a pair becomes an edge when its ``fit`` and ``fitness`` are high
       enough; odometry-like (never pruned) when its ``fit`` is very high, clearly
       ahead of its ``rival_fit`` and the pairwise call did not warn about it (its
       ``confidence``), uncertain otherwise (:class:`MultiwayOption`); each
       edge's information matrix is Open3D's ``get_information_matrix_from_point_clouds``
       on the down-sampled clouds;
    3. **tree**: the initial poses chained along a maximum spanning tree of the edges
       weighted by ``fit`` (those not clearly ahead of their ``rival_fit``, then those
       warned about, last), from the first cloud; with ``camera_locations``, a join
       that would put points of one branch's clouds in space another's camera saw
       empty is passed over; clouds it does not reach are
       ``unconnected``, and those that only chains through warned pairs reach are
       ``doubtful``; the edges that disagree with those poses are dropped (a
       symmetric object's pairs may each be right up to a different symmetry), and a
       cloud that only weak tree edges place while its other pairs disagree is left
       unconnected;
    4. **optimisation**: Open3D's ``global_optimization`` (Levenberg-Marquardt, line
       process with ``option.edge_prune_threshold``, reference node 0);
    5. **refinement** (``option.refine``, off by default): every pair overlapping at the
       optimised poses registered again by point-to-plane ICP from them, and the graph
       optimised again.

    The pairwise calls' low-confidence warnings are not logged during the call (scans
    that do not overlap fit poorly, and the selection expects it); each pair's ``fit`` is
    in ``result.pairs``.

    Parameters
    ----------
    clouds : sequence of PointCloud, tensor PointCloud or ndarray
        Two or more clouds in metres (``open3d.geometry.PointCloud``,
        ``open3d.t.geometry.PointCloud``, or numpy arrays of shape (N, 3), or (N, 6) with
        normals), each in its own frame. None is modified.
    voxel_size : float
        Voxel edge, metres, of every pairwise registration.
    option : MultiwayOption, optional
        Pairs, selection, optimisation, threads and progress.
    camera_locations : sequence of (array_like of shape (3,), or None), optional
        Where each cloud was seen from, one entry per cloud (an array of shape (n, 3)
        will do): its camera's position in the cloud's own frame, metres (``(0, 0, 0)``
        for a depth frame or a fragment in its camera's frame); None for a cloud seen
        from no one place (a merged model). Given, the spanning tree places no cloud
        where more than ``MultiwayOption.max_free_space`` of its points would lie in
        space another cloud's camera saw empty: scans of a room whose floor and walls
        fit as well in the wrong place. None (the default): no test.

    Returns
    -------
    MultiwayResult
        ``poses[k]`` maps cloud ``k`` into the first cloud's frame (4x4, float64, rigid;
        the identity for the first), None for a cloud in ``unconnected``.

    Raises
    ------
    ValueError, TypeError
        For fewer than two clouds, a cloud the registration refuses (the message names
        ``clouds[k]``), clouds whose extents differ by 50x or more (in different units;
        the message names both clouds and extents), a bad ``voxel_size`` or option, or
        ``camera_locations`` not one position (or None) per cloud (naming
        ``camera_locations[k]``).

    Examples
    --------
    >>> result = o3d_spectral.registration_multiway(scans, 0.005)  # doctest: +SKIP
    >>> placed = [o3d.geometry.PointCloud(scan).transform(pose)  # doctest: +SKIP
    ...           for scan, pose in zip(scans, result.poses) if pose is not None]
    """
    start = time.perf_counter()
    voxel_size = check_voxel_size(voxel_size)
    check_instance("option", option, MultiwayOption)
    option = option or MultiwayOption()
    arrays = checked_clouds(clouds)
    checked_cameras(camera_locations, len(arrays))  # refused before any work
    sources, targets = _prepared(arrays, voxel_size, option.workers)
    with _quiet_low_fit():
        records = _register_pairs(sources, targets, pair_list(len(arrays), option),
                                  voxel_size, option)
    log.info("%d of %d pairs pass the selection, %d of them odometry-like",
             *_kept_counts(records, option))
    result = poses_from_pairs(arrays, voxel_size, records, option=option,
                              camera_locations=camera_locations)
    return dataclasses.replace(result, run_time=time.perf_counter() - start)


class _LowFitFilter(logging.Filter):
    """Drops the pairwise calls' low-confidence warnings."""

    def filter(self, record: logging.LogRecord) -> bool:
        return not record.getMessage().startswith("low confidence")


@contextlib.contextmanager
def _quiet_low_fit() -> Iterator[None]:
    """The diagnostics' low-confidence warnings left unlogged during the block: between scans
    that do not overlap a low fit is expected, and the selection handles it."""
    quiet = _LowFitFilter()
    logging.getLogger(diagnostics.__name__).addFilter(quiet)
    try:
        yield
    finally:
        logging.getLogger(diagnostics.__name__).removeFilter(quiet)


def _kept_counts(records: list[PairwiseRecord], option: MultiwayOption) -> tuple[int, ...]:
    """(kept pairs, pairs, odometry-like pairs) under ``option``'s selection."""
    chosen = [selected(r, option) for r in records]
    return (sum(r.kept for r in chosen), len(chosen),
            sum(r.kept and not r.uncertain for r in chosen))


def _prepared(
    arrays: list[CloudArrays], voxel_size: float, workers: int | None
) -> tuple[list[PreparedSource], list[PreparedTarget]]:
    """Each cloud prepared once as a source and once as a target."""
    jobs = [(kind, a) for kind in (prepare, prepare_target) for a in arrays]
    done = thread_map(lambda job: job[0](job[1], voxel_size), jobs, workers)
    return done[:len(arrays)], done[len(arrays):]


def pair_list(n: int, option: MultiwayOption) -> list[tuple[int, int]]:
    """The pairs ``(i, j)``, ``i < j``, registered among ``n`` clouds, sorted: all of them
    up to ``option.max_all_pairs`` clouds, else each cloud with its ``option.neighbours``
    successors, cyclically."""
    if n <= option.max_all_pairs:
        return list(itertools.combinations(range(n), 2))
    near = {tuple(sorted((i, (i + k) % n))) for i in range(n)
            for k in range(1, min(option.neighbours, n - 1) + 1)}
    return sorted(near)


def _register_pairs(
    sources: list[PreparedSource], targets: list[PreparedTarget],
    pairs: list[tuple[int, int]], voxel_size: float, option: MultiwayOption,
) -> list[PairwiseRecord]:
    """Each pair registered (source the first cloud, target the second), in the pairs'
    order, on ``option.workers`` threads; ``option.progress`` told after each."""
    lock, done = threading.Lock(), [0]

    def register(pair: tuple[int, int]) -> PairwiseRecord:
        i, j = pair
        result = registration_spectral_global(sources[i], targets[j], voxel_size,
                                              search=option.search)
        if option.progress is not None:
            with lock:
                done[0] += 1
                option.progress(done[0], len(pairs))
        return PairwiseRecord(i, j, np.array(result.transformation, dtype=np.float64),
                              float(result.fitness), float(result.fit),
                              float(result.rival_fit), kept=False, uncertain=True,
                              confidence=float(result.confidence))

    return thread_map(register, pairs, option.workers)


