"""Settings and results of :func:`o3d_spectral.registration_multiway`."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import open3d as o3d
from numpy.typing import NDArray

from ..common.checks import check_bool, check_instance, check_int, check_number
from ..evidence.confidence import WARN_BELOW
from ..search.options import GlobalSearchOption

__all__ = ["MultiwayOption", "PairwiseRecord", "MultiwayResult"]


@dataclass(frozen=True)
class MultiwayOption:
    """How :func:`o3d_spectral.registration_multiway` pairs, selects and optimises.

    Attributes
    ----------
    max_all_pairs : int, default 12
        Up to this many clouds, every pair is registered: ``n (n - 1) / 2`` calls (28 for
        8 clouds, 66 for 12). Beyond, each cloud is registered with the ``neighbours``
        clouds that follow it in the list, cyclically (``n * neighbours`` calls): the
        clouds are then taken to be in capture order.
    neighbours : int, default 4
        See ``max_all_pairs``.
    min_fit : float, default 0.3
        A pair's result becomes an edge of the pose graph only when its ``fit`` is at
        least this and its ``fitness`` at least ``min_fitness`` (and it agrees with the
        tree: ``cycle_degrees``).
    min_fitness : float, default 0.1
        See ``min_fit``.
    min_confidence : float, default 0.5
        A kept pair whose calibrated ``confidence`` (the probability that its pose is
        right) is under this, a pair the pairwise call warns about (the threshold of its
        warning, :data:`o3d_spectral.evidence.confidence.WARN_BELOW`), joins the spanning
        tree only where no confident pair does, is never odometry-like, and a cloud that
        only such pairs link to the first is reported ``doubtful``. Pairs whose method
        gives no confidence (``PairwiseRecord.confidence`` None) count as confident.
    rival_margin : float, default 0.05
        A pair whose ``fit`` leads its ``rival_fit`` by less (its best pose does not fit
        clearly better than a distinct one) joins the spanning tree only where no leading
        pair does; it may still be an edge (views of a symmetric object have a rival as
        good: their symmetric pose).
    cycle_degrees : float, default 10.0
        A kept pair becomes an edge only when it agrees with the poses chained along the
        maximum spanning tree: within this angle and ``cycle_voxels`` of them (pairs of
        views of a symmetric object may each be right up to a different symmetry).
    cycle_voxels : float, default 4.0
        See ``cycle_degrees``; measured at the source cloud's centroid, in voxels.
    certain_fit : float, default 0.8
        A kept edge whose ``fit`` is at least this and leads its ``rival_fit`` by
        ``certain_margin`` is added as odometry-like (``uncertain=False``: never pruned
        by the optimisation's line process); the other kept edges are uncertain.
    certain_margin : float, default 0.2
        See ``certain_fit``.
    distance_voxels : float, default 1.5
        The optimisation's ``max_correspondence_distance``, and the reach of the
        information matrices and of the refinement's ICP, in voxels.
    edge_prune_threshold : float, default 0.25
        Open3D's line-process threshold: an uncertain edge whose weight falls under it is
        dropped and the graph optimised again.
    max_free_space : float, default 0.05
        Where the clouds' camera positions are given (``camera_locations``), two clouds
        join the spanning tree only where at most this share of either's points (among
        those in directions the other's camera saw) lies in space the other's camera saw
        empty: nearer to it than the surface it measured there
        (:mod:`o3d_spectral.multiway.visibility`). Every cloud of one branch is tested
        against every cloud of the other, not only the pair that joins them. Measured on
        three synthetic rooms' fragments (``eval/bench_multiway.py --rooms 3``; each
        fused from five depth frames, the first frame's camera given): the true poses of
        the 198 pairs put 4 over 0.02 and 1 over 0.05 (0.145 at most: a fragment seen
        from five places, tested from one), the 319 wrong pairwise results of both
        pipelines 273 and 267 (median 0.19).
    refine : bool, default False
        After the first optimisation, each pair whose clouds overlap at the optimised
        poses (ICP ``fitness`` at least ``refine_min_fitness``) is registered again by
        point-to-plane ICP from those poses and the graph of those edges optimised again.
        Off by default: on ``eval/bench_multiway.py`` it placed the same scans and did
        not lower their errors (``docs/multiway.md``).
    refine_min_fitness : float, default 0.3
        See ``refine``.
    search : GlobalSearchOption, default ``GlobalSearchOption(rotations="adaptive")``
        The search of each pairwise :func:`o3d_spectral.registration_spectral_global`.
        Adaptive, not the single call's ``"auto"``: in an unordered set most pairs share
        nothing and each of those is doubted, which on the CPU escalates it to the dense
        search; on ``eval/bench_multiway.py`` at commit 6c1e8cf, against the stored runs
        of 6f89d47 and 06ce43f, that took the dragon's scans 84 s against 41 and room
        300's fragments 427 s against 162, and placed the same scans right.
    workers : int or None, default None
        Threads the pairwise registrations run on (all cores when None). The result is
        the same whatever the number.
    progress : callable or None, default None
        Called as ``progress(done, total)`` after each pairwise registration (from the
        worker threads, one call at a time).
    """

    max_all_pairs: int = 12
    neighbours: int = 4
    min_fit: float = 0.3
    min_fitness: float = 0.1
    min_confidence: float = WARN_BELOW
    rival_margin: float = 0.05
    cycle_degrees: float = 10.0
    cycle_voxels: float = 4.0
    certain_fit: float = 0.8
    certain_margin: float = 0.2
    distance_voxels: float = 1.5
    edge_prune_threshold: float = 0.25
    max_free_space: float = 0.05
    refine: bool = False
    refine_min_fitness: float = 0.3
    search: GlobalSearchOption = GlobalSearchOption(rotations="adaptive")
    workers: int | None = None
    progress: Callable[[int, int], None] | None = None

    def __post_init__(self) -> None:
        check_int("max_all_pairs", self.max_all_pairs, low=2)
        check_int("neighbours", self.neighbours, low=1)
        for name in ("min_fit", "min_fitness", "min_confidence", "certain_fit",
                     "refine_min_fitness", "edge_prune_threshold", "max_free_space"):
            check_number(name, getattr(self, name), low=0.0, high=1.0)
        for name in ("rival_margin", "certain_margin"):
            check_number(name, getattr(self, name), low=-1.0, high=1.0)
        check_number("cycle_degrees", self.cycle_degrees, low=0.0, high=180.0)
        for name in ("distance_voxels", "cycle_voxels"):
            check_number(name, getattr(self, name), low=0.0, low_open=True)
        check_bool("refine", self.refine)
        check_instance("search", self.search, GlobalSearchOption, optional=False)
        check_int("workers", self.workers, low=1, optional=True)
        if self.progress is not None and not callable(self.progress):
            raise TypeError(f"progress must be callable or None, got "
                            f"{type(self.progress).__qualname__}")


@dataclass(frozen=True)
class PairwiseRecord:
    """One pairwise registration of :func:`o3d_spectral.registration_multiway`.

    Attributes
    ----------
    source, target : int
        Indices of the clouds (``source < target``).
    transformation : ndarray, shape (4, 4), float64
        The pairwise result: maps the source cloud's points onto the target cloud's.
    fitness, fit, rival_fit : float
        The pairwise result's (:class:`o3d_spectral.SpectralRegistrationResult`).
    kept : bool
        The result became an edge of the first pose graph: it passed the selection and
        agrees with the tree (:class:`MultiwayOption` ``min_fit``, ``cycle_degrees``).
    uncertain : bool
        A kept edge the line process may prune (see ``certain_fit``).
    confidence : float or None
        The pairwise result's calibrated confidence
        (:attr:`o3d_spectral.SpectralRegistrationResult.confidence`); None for a method
        that gives none.
    determined : bool
        Neither cloud leaves a rigid motion free
        (:func:`o3d_spectral.evidence.free_motions.leaves_motion_free`): a view showing only a
        body of revolution (a mug with its handle hidden) fixes a pair's pose up to a turn
        about its axis at best, however well it fits. Set from the clouds.
    """

    source: int
    target: int
    transformation: NDArray[np.float64]
    fitness: float
    fit: float
    rival_fit: float
    kept: bool
    uncertain: bool
    confidence: float | None = None
    determined: bool = True


@dataclass(frozen=True)
class MultiwayResult:
    """What :func:`o3d_spectral.registration_multiway` returns.

    Attributes
    ----------
    poses : tuple of (ndarray, shape (4, 4), float64) or None
        Each cloud's pose in the first cloud's frame (``p_first = pose @ p``, rigid); None
        for a cloud in ``unconnected``.
    pose_graph : open3d.pipelines.registration.PoseGraph
        The optimised graph: one node per connected cloud, in the order of ``nodes``,
        its edges those left after the line process's pruning.
    nodes : tuple of int
        The cloud index of each node of ``pose_graph`` (the first is 0).
    pairs : tuple of PairwiseRecord
        Every pairwise registration, in the order the pairs were listed.
    unconnected : tuple of int
        Clouds no chain of kept edges links to the first cloud: reported, not placed.
    doubtful : tuple of int
        Placed clouds that no chain of kept, confident edges links to the first cloud
        (``MultiwayOption.min_confidence``): each chain that places them passes through a
        pair the pairwise call warned about, so their poses may be wrong.
    run_time : float
        Seconds.
    """

    poses: tuple[NDArray[np.float64] | None, ...]
    pose_graph: o3d.pipelines.registration.PoseGraph
    nodes: tuple[int, ...]
    pairs: tuple[PairwiseRecord, ...]
    unconnected: tuple[int, ...]
    run_time: float
    doubtful: tuple[int, ...] = ()
