"""The building blocks of Open3D's global-registration tutorial, shared by the harness'
FPFH baselines (:mod:`o3d_spectral.harness.methods`) and its peers
(:mod:`o3d_spectral.harness.peers`): FPFH features, a seeded global match, the
point-to-plane refinement on the full clouds, and their settings (sizes in voxels)."""

from __future__ import annotations

import numpy as np
import open3d as o3d

from o3d_spectral.refinement.icp import TUTORIAL_DISTANCE, point_to_plane_refinement

__all__ = ["FPFH", "REFINEMENT", "LEAN_REFINEMENT", "RANSAC", "open3d_fields",
           "fpfh_features", "global_then_refine", "with_target_normals", "ransac_matcher",
           "lean_refinement"]

_reg = o3d.pipelines.registration


def open3d_fields(options, names: tuple[str, ...]) -> dict:
    """The named attributes of an Open3D options object, as a dict."""
    return {name: getattr(options, name) for name in names}


#: The global-registration tutorial's FPFH features (sizes in voxels).
FPFH = {
    "down_sample_voxels": 1.0,
    "normal_radius_voxels": 2.0,
    "normal_max_nn": 30,
    "feature_radius_voxels": 5.0,
    "feature_max_nn": 100,
}

#: The tutorial's refinement after a global registration, on the full clouds
#: (:func:`o3d_spectral.registration.point_to_plane_refinement`).
REFINEMENT = {
    "estimation": "point_to_plane",
    "max_correspondence_distance_voxels": TUTORIAL_DISTANCE,
    "criteria": open3d_fields(
        _reg.ICPConvergenceCriteria(), ("max_iteration", "relative_fitness", "relative_rmse")
    ),
}

#: The refinement as users tune it for speed: the same ICP on both clouds thinned to half
#: the voxel, the target's normals estimated there (as the features' are); on raw scans it
#: takes half the tutorial's time and registers as often, as accurately.
LEAN_REFINEMENT = REFINEMENT | {"down_sample_voxels": 0.5}

#: FPFH-RANSAC's matching (the tutorial's; distances in voxels).
RANSAC = {
    "mutual_filter": True,
    "max_correspondence_distance_voxels": 1.5,
    "estimation": "point_to_point",
    "with_scaling": False,
    "ransac_n": 3,
    "edge_length_checker": 0.9,
    "distance_checker_voxels": 1.5,
    "max_iteration": 100000,
    "confidence": 0.999,
}

def fpfh_features(cloud: o3d.geometry.PointCloud, voxel_size: float, features: dict = FPFH):
    """FPFH features (the global-registration tutorial's by default): down-sample at ``v``,
    normals with radius ``normal_radius_voxels * v`` (``2v``), FPFH with radius
    ``feature_radius_voxels * v`` (``5v``)."""
    down = cloud.voxel_down_sample(features["down_sample_voxels"] * voxel_size)
    down.estimate_normals(
        o3d.geometry.KDTreeSearchParamHybrid(
            radius=features["normal_radius_voxels"] * voxel_size, max_nn=features["normal_max_nn"]
        )
    )
    feature = _reg.compute_fpfh_feature(
        down,
        o3d.geometry.KDTreeSearchParamHybrid(
            radius=features["feature_radius_voxels"] * voxel_size,
            max_nn=features["feature_max_nn"],
        ),
    )
    return down, feature


def global_then_refine(
    source, target, voxel_size: float, seed: int, match, features: dict = FPFH, *,
    lean: bool = False,
) -> np.ndarray:
    """FPFH features of both clouds (``features``: sizes in voxels, the tutorial's by
    default), the global registration ``match(source_down, target_down, source_fpfh,
    target_fpfh)`` (seeded), then the tutorial's point-to-plane refinement on the full
    clouds (:func:`o3d_spectral.refinement.icp.point_to_plane_refinement`; a target without
    normals gets them first, :func:`with_target_normals`), or with ``lean`` on both clouds
    thinned to half the voxel (:func:`lean_refinement`); returns the 4x4 estimate."""
    if not lean:  # before the features: given normals orient the features' estimate
        target = with_target_normals(target, voxel_size)
    source_down, source_fpfh = fpfh_features(source, voxel_size, features)
    target_down, target_fpfh = fpfh_features(target, voxel_size, features)
    o3d.utility.random.seed(seed)
    coarse = match(source_down, target_down, source_fpfh, target_fpfh).transformation
    if lean:
        return lean_refinement(source, target, voxel_size, coarse)
    return point_to_plane_refinement(source, target, voxel_size, coarse)


def lean_refinement(
    source: o3d.geometry.PointCloud, target: o3d.geometry.PointCloud, voxel_size: float,
    init: np.ndarray,
) -> np.ndarray:
    """The tutorial's point-to-plane refinement from ``init`` (4, 4) on both clouds thinned
    to :data:`LEAN_REFINEMENT`'s ``down_sample_voxels`` (half the voxel, metres), the
    thinned target's normals estimated as the features' are (its own normals when given
    are averaged by the thinning)."""
    thin = LEAN_REFINEMENT["down_sample_voxels"] * voxel_size
    source, target = source.voxel_down_sample(thin), target.voxel_down_sample(thin)
    if not target.has_normals():
        target.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(
            radius=FPFH["normal_radius_voxels"] * voxel_size, max_nn=FPFH["normal_max_nn"]
        ))
    return point_to_plane_refinement(source, target, voxel_size, init)


def with_target_normals(
    target: o3d.geometry.PointCloud, voxel_size: float
) -> o3d.geometry.PointCloud:
    """``target``, or, when it has no normals (a raw scan), a copy with normals estimated
    as the tutorial's features' are (radius ``normal_radius_voxels`` voxels of
    ``voxel_size``, metres; ``normal_max_nn`` neighbours): the tutorial's point-to-plane
    refinement needs them. Called inside the methods, so the estimate is in their time."""
    if target.has_normals():
        return target
    target = o3d.geometry.PointCloud(target)
    target.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(
        radius=FPFH["normal_radius_voxels"] * voxel_size, max_nn=FPFH["normal_max_nn"]
    ))
    return target


def ransac_matcher(
    voxel_size: float, *, max_iteration: int = RANSAC["max_iteration"],
    confidence: float = RANSAC["confidence"],
):
    """The tutorial's RANSAC on FPFH matches (:data:`RANSAC`), as a ``match`` for
    :func:`global_then_refine`; stopped at ``max_iteration`` iterations or
    ``confidence`` (the tutorial's when omitted)."""
    distance = RANSAC["max_correspondence_distance_voxels"] * voxel_size
    checkers = [
        _reg.CorrespondenceCheckerBasedOnEdgeLength(RANSAC["edge_length_checker"]),
        _reg.CorrespondenceCheckerBasedOnDistance(RANSAC["distance_checker_voxels"] * voxel_size),
    ]

    def ransac(source_down, target_down, source_fpfh, target_fpfh):
        return _reg.registration_ransac_based_on_feature_matching(
            source_down,
            target_down,
            source_fpfh,
            target_fpfh,
            RANSAC["mutual_filter"],
            distance,
            _reg.TransformationEstimationPointToPoint(RANSAC["with_scaling"]),
            RANSAC["ransac_n"],
            checkers,
            _reg.RANSACConvergenceCriteria(max_iteration, confidence),
        )

    return ransac
