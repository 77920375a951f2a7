"""Peers from other packages, and FPFH-RANSAC with features sized on a tuning split.

* ``kiss_matcher``: KISS-Matcher (``pip install kiss-matcher``; Lim et al., ICRA 2025:
  Faster-PFH features, graph-theoretic pruning, GNC solver), a global method, on both
  clouds down-sampled at the voxel size ``v`` with its resolution set to ``v`` (its other
  settings its defaults), then the same point-to-plane refinement as FPFH-RANSAC; on one
  thread like every method the harness runs (see :func:`kiss_matcher`);
* ``small_gicp``: small_gicp's GICP (``pip install small-gicp``) from the identity, a local
  peer of Open3D's ICP: both clouds down-sampled at ``v``, covariances from 10 neighbours,
  correspondences up to ``5v``, at most 100 iterations, one thread;
* ``fpfh_ransac_tuned``: the tutorial's FPFH-RANSAC and refinement with the feature and
  normal radii chosen by ``eval/tune_fpfh.py`` on the tuning split
  (:data:`~o3d_spectral.harness.selection.TUNING_SPLIT`); it runs on the other instances
  only (its settings carry ``tuning_split``, which the runner reads).

The first two are listed by :func:`available_peers` only when their package imports
(``pip install 'o3d-spectral[peers]'``); otherwise :func:`missing_peers` says how to install
it. :mod:`o3d_spectral.harness.methods` registers them; this module registers nothing.
"""

from __future__ import annotations

import contextlib
import functools
import importlib
import importlib.util
import os
from collections.abc import Callable, Iterator

import numpy as np

from o3d_spectral.harness import tutorial
from o3d_spectral.harness.baselines import ICP_DISTANCE_VOXELS, ICP_MAX_ITERATION
from o3d_spectral.harness.selection import TUNING_SPLIT
from o3d_spectral.refinement.icp import point_to_plane_refinement

__all__ = [
    "FPFH_TUNING_GRID",
    "KISS_MATCHER",
    "SMALL_GICP",
    "TUNED",
    "TUNED_FPFH",
    "available_peers",
    "fpfh_ransac_with",
    "missing_peers",
]

_HINT = "pip install 'o3d-spectral[peers]'"

#: KISS-Matcher's settings (distances in voxels; the rest are its defaults).
KISS_MATCHER = {
    "down_sample_voxels": 1.0,
    "resolution_voxels": 1.0,
    "config": "KISSMatcherConfig defaults otherwise (normal_r_gain 3, fpfh_r_gain 5, ...)",
    "threads": 1,
    "refinement": tutorial.REFINEMENT,
}

#: small_gicp's GICP (distances in voxels); the convergence tolerances are its defaults.
SMALL_GICP = {
    "init": "identity",
    "registration_type": "GICP",
    "down_sample_voxels": 1.0,
    "num_neighbors": 10,
    "max_correspondence_distance_voxels": ICP_DISTANCE_VOXELS,
    "max_iterations": ICP_MAX_ITERATION,
    "rotation_epsilon_rad": 0.1 * np.pi / 180.0,
    "translation_epsilon_m": 1e-3,
    "num_threads": 1,
}

#: The grid ``eval/tune_fpfh.py`` searches (radii in voxels).
FPFH_TUNING_GRID = {
    "feature_radius_voxels": (1.5, 2.0, 2.5, 3.5, 5.0),
    "normal_radius_voxels": (1.0, 1.5, 2.0),
}

#: The tuned features: the tutorial's with the radii ``eval/tune_fpfh.py`` chose on the
#: tuning split of the seed-0 suites (240 instances; 52.1% against the tutorial's 43.3%;
#: docs/results/fpfh_tuning.txt). 1 voxel is the smallest normal radius that still finds
#: neighbours on clouds down-sampled at the voxel size.
TUNED_FPFH = tutorial.FPFH | {"feature_radius_voxels": 3.5, "normal_radius_voxels": 1.0}


def _available(module: str) -> bool:
    """Whether ``module`` imports (a broken install is as good as none)."""
    if importlib.util.find_spec(module) is None:
        return False
    try:
        importlib.import_module(module)
    except Exception:  # noqa: BLE001 - any failure to import means "not available"
        return False
    return True


@contextlib.contextmanager
def _on_one_cpu() -> Iterator[None]:
    """The process's CPU affinity narrowed to one CPU inside the block, then restored."""
    allowed = os.sched_getaffinity(0)
    os.sched_setaffinity(0, {min(allowed)})
    try:
        yield
    finally:
        os.sched_setaffinity(0, allowed)


@functools.cache
def _one_tbb_thread() -> None:
    """Size oneTBB's thread pool in this process to one thread.

    KISS-Matcher's wheel runs parts of its pipeline on its own oneTBB, which neither
    ``OMP_NUM_THREADS`` nor Open3D's thread setting reaches. oneTBB sizes its pool once, from
    the CPUs the process may run on when it is first used; a first call on one CPU leaves
    it at one thread for the life of the process, whatever the affinity afterwards.
    """
    import kiss_matcher as km

    with _on_one_cpu():
        points = np.random.default_rng(0).random((64, 3), dtype=np.float32)
        km.KISSMatcher(km.KISSMatcherConfig(voxel_size=0.1)).estimate(points, points)


def kiss_matcher(source, target, voxel_size: float, seed: int) -> tuple[np.ndarray, dict]:
    """KISS-Matcher at resolution ``v`` on the clouds down-sampled at ``v``, then the
    point-to-plane refinement on the full clouds.

    It runs on one thread, like every method in the harness: on several, its oneTBB
    threads made a seeded run's rows differ between machines and between runs (a rotation
    error of 55.43 against 54.96 degrees for one instance, run twice on one machine).
    """
    import kiss_matcher as km

    _one_tbb_thread()
    points = [
        np.asarray(cloud.voxel_down_sample(voxel_size).points, dtype=np.float32)
        for cloud in (source, target)
    ]
    matcher = km.KISSMatcher(km.KISSMatcherConfig(voxel_size=voxel_size))
    solution = matcher.estimate(points[0], points[1])
    coarse = np.eye(4)
    if solution.valid:
        coarse[:3, :3] = np.asarray(solution.rotation, dtype=np.float64)
        coarse[:3, 3] = np.asarray(solution.translation, dtype=np.float64).ravel()
    target = tutorial.with_target_normals(target, voxel_size)
    return point_to_plane_refinement(source, target, voxel_size, coarse), {}


def small_gicp(source, target, voxel_size: float, seed: int) -> tuple[np.ndarray, dict]:
    """small_gicp's GICP from the identity (:data:`SMALL_GICP`)."""
    import small_gicp as sg

    prepared = [
        sg.preprocess_points(
            np.asarray(cloud.points, dtype=np.float64),
            downsampling_resolution=voxel_size,
            num_neighbors=SMALL_GICP["num_neighbors"],
            num_threads=1,
        )
        for cloud in (target, source)
    ]
    (target_cloud, target_tree), (source_cloud, _) = prepared
    result = sg.align(
        target_cloud,
        source_cloud,
        target_tree,
        np.eye(4),
        registration_type="GICP",
        max_correspondence_distance=SMALL_GICP["max_correspondence_distance_voxels"] * voxel_size,
        num_threads=1,
        max_iterations=SMALL_GICP["max_iterations"],
        rotation_epsilon=SMALL_GICP["rotation_epsilon_rad"],
        translation_epsilon=SMALL_GICP["translation_epsilon_m"],
    )
    info = {"iterations": int(result.iterations), "converged": bool(result.converged)}
    return np.asarray(result.T_target_source, dtype=np.float64), info


def fpfh_ransac_with(features: dict):
    """FPFH-RANSAC and the refinement, as the tutorial's but with ``features``."""

    def method(source, target, voxel_size: float, seed: int) -> tuple[np.ndarray, dict]:
        match = tutorial.ransac_matcher(voxel_size)
        return tutorial.global_then_refine(source, target, voxel_size, seed, match, features), {}

    return method


#: The peers from other packages: name, module, package on PyPI, method, settings.
_PEERS = (
    ("kiss_matcher", "kiss_matcher", "kiss-matcher", kiss_matcher, KISS_MATCHER),
    ("small_gicp", "small_gicp", "small-gicp", small_gicp, SMALL_GICP),
)


def available_peers() -> list[tuple[str, Callable[..., tuple[np.ndarray, dict]], dict]]:
    """The peers whose package imports here: name, method, settings."""
    return [(name, method, settings) for name, module, _, method, settings in _PEERS
            if _available(module)]


def missing_peers() -> dict[str, str]:
    """The peers whose package is missing here, and how to install it, by name."""
    return {
        name: f"the 'peers' extra ({package} is missing): {_HINT}"
        for name, module, package, _, _ in _PEERS
        if not _available(module)
    }


#: FPFH-RANSAC with the tuned features: name, method, settings.
TUNED = (
    "fpfh_ransac_tuned",
    fpfh_ransac_with(TUNED_FPFH),
    {
        "features": TUNED_FPFH,
        "tuning_split": TUNING_SPLIT,
        "tuning_grid": FPFH_TUNING_GRID,
        "ransac": tutorial.RANSAC,
        "refinement": tutorial.REFINEMENT,
    },
)
