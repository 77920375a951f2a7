"""Open3D's registration methods compared with the spectral calls, as harness methods.

* ``icp_point_to_point``, ``icp_point_to_plane``: Open3D's ICP from the identity on both
  clouds down-sampled at the voxel size ``v``, correspondences up to ``5v``, at most 100
  iterations;
* ``fpfh_ransac``: Open3D's global-registration tutorial (FPFH + RANSAC), then the
  point-to-plane refinement on the full clouds (:mod:`o3d_spectral.harness.tutorial`);
* ``fpfh_ransac_lean``: the same features and RANSAC, the refinement on both clouds
  thinned to half the voxel: FPFH-RANSAC as users tune it for speed, the reference of
  the speed benchmark's ratios;
* ``fgr``: Fast Global Registration on the tutorial's features, then the same refinement.

Each has the harness's signature ``(source, target, voxel_size, seed) -> (transformation,
info)``; :data:`BASELINES` lists them with their settings, for
:mod:`o3d_spectral.harness.methods` to register.
"""

from __future__ import annotations

import numpy as np
import open3d as o3d

from o3d_spectral.harness.constants import (
    FGR_DISTANCE_VOXELS,
    ICP_DISTANCE_VOXELS,
    ICP_MAX_ITERATION,
)
from o3d_spectral.harness.tutorial import (
    FPFH,
    LEAN_REFINEMENT,
    RANSAC,
    REFINEMENT,
    global_then_refine,
    open3d_fields,
    ransac_matcher,
)

__all__ = [
    "BASELINES",
    "FGR",
    "ICP_DISTANCE_VOXELS",
    "ICP_MAX_ITERATION",
    "ICP_SETTINGS",
    "fgr",
    "fpfh_ransac",
    "fpfh_ransac_lean",
    "icp_point_to_plane",
    "icp_point_to_point",
]

_registration = o3d.pipelines.registration


#: The ICP baselines' settings (distances in voxels).
ICP_SETTINGS = {
    "init": "identity",
    "down_sample_voxels": 1.0,
    "max_correspondence_distance_voxels": ICP_DISTANCE_VOXELS,
    "criteria": open3d_fields(
        _registration.ICPConvergenceCriteria(max_iteration=ICP_MAX_ITERATION),
        ("max_iteration", "relative_fitness", "relative_rmse"),
    ),
}

FGR = {"maximum_correspondence_distance_voxels": FGR_DISTANCE_VOXELS} | open3d_fields(
    _registration.FastGlobalRegistrationOption(),
    (
        "decrease_mu",
        "division_factor",
        "iteration_number",
        "maximum_tuple_count",
        "tuple_scale",
        "tuple_test",
        "use_absolute_scale",
    ),
)


def _down_sampled(cloud: o3d.geometry.PointCloud, voxel_size: float) -> o3d.geometry.PointCloud:
    """Voxel down-sampling keeping the given normals (re-normalised after averaging)."""
    down = cloud.voxel_down_sample(voxel_size)
    down.normalize_normals()
    return down


def _icp_from_identity(source, target, voxel_size: float, estimation) -> tuple[np.ndarray, dict]:
    result = _registration.registration_icp(
        _down_sampled(source, voxel_size),
        _down_sampled(target, voxel_size),
        ICP_DISTANCE_VOXELS * voxel_size,
        np.eye(4),
        estimation,
        _registration.ICPConvergenceCriteria(max_iteration=ICP_MAX_ITERATION),
    )
    return np.asarray(result.transformation), {}


def icp_point_to_point(source, target, voxel_size: float, seed: int) -> tuple[np.ndarray, dict]:
    """Open3D point-to-point ICP from the identity on clouds down-sampled at the voxel size."""
    estimation = _registration.TransformationEstimationPointToPoint()
    return _icp_from_identity(source, target, voxel_size, estimation)


def icp_point_to_plane(source, target, voxel_size: float, seed: int) -> tuple[np.ndarray, dict]:
    """Open3D point-to-plane ICP from the identity (the clouds' own normals)."""
    return _icp_from_identity(
        source, target, voxel_size, _registration.TransformationEstimationPointToPlane()
    )


def fpfh_ransac(source, target, voxel_size: float, seed: int) -> tuple[np.ndarray, dict]:
    """Open3D's global-registration tutorial: FPFH + RANSAC, then point-to-plane ICP.

    Mutual filter, inlier distance ``1.5 v``, edge-length (0.9) and distance checkers,
    3-point samples, at most 100000 iterations at confidence 0.999.
    """
    return global_then_refine(source, target, voxel_size, seed, ransac_matcher(voxel_size)), {}


def fpfh_ransac_lean(source, target, voxel_size: float, seed: int) -> tuple[np.ndarray, dict]:
    """:func:`fpfh_ransac` with its point-to-plane refinement on both clouds thinned to half
    the voxel (:func:`o3d_spectral.harness.tutorial.lean_refinement`)."""
    match = ransac_matcher(voxel_size)
    return global_then_refine(source, target, voxel_size, seed, match, lean=True), {}


def fgr(source, target, voxel_size: float, seed: int) -> tuple[np.ndarray, dict]:
    """Open3D Fast Global Registration on the tutorial's FPFH features (distance
    ``0.5 v``), then the same point-to-plane ICP refinement."""
    option = _registration.FastGlobalRegistrationOption(
        maximum_correspondence_distance=FGR_DISTANCE_VOXELS * voxel_size
    )

    def fast_global(source_down, target_down, source_fpfh, target_fpfh):
        return _registration.registration_fgr_based_on_feature_matching(
            source_down, target_down, source_fpfh, target_fpfh, option
        )

    return global_then_refine(source, target, voxel_size, seed, fast_global), {}


#: Open3D's methods in the order they are registered: name, method, settings.
BASELINES = (
    ("icp_point_to_point", icp_point_to_point,
     {"estimation": "point_to_point", **ICP_SETTINGS}),
    ("icp_point_to_plane", icp_point_to_plane,
     {"estimation": "point_to_plane", **ICP_SETTINGS}),
    ("fpfh_ransac", fpfh_ransac, {"features": FPFH, "ransac": RANSAC, "refinement": REFINEMENT}),
    ("fpfh_ransac_lean", fpfh_ransac_lean,
     {"features": FPFH, "ransac": RANSAC, "refinement": LEAN_REFINEMENT}),
    ("fgr", fgr, {"features": FPFH, "fgr": FGR, "refinement": REFINEMENT}),
)
