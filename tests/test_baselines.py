"""Open3D's baselines in the harness: the lean FPFH-RANSAC, as users tune it for speed."""

import numpy as np
import open3d as o3d

from o3d_spectral.harness import tutorial
from o3d_spectral.harness.errors import rotation_error, translation_error
from o3d_spectral.harness.methods import get_method, method_settings
from o3d_spectral.spectra import so3
from tests.conftest import sample_model

VOXEL = 0.008


def _dense_pair():
    """A dense drill (30k points, no normals) and a copy turned 40 degrees and shifted."""
    source = sample_model("power_drill", 30000)
    source.normals = o3d.utility.Vector3dVector()
    T = np.eye(4)
    T[:3, :3] = so3.exp(np.deg2rad(40.0) * np.array([0.0, 0.6, 0.8]))
    T[:3, 3] = (0.05, -0.02, 0.01)
    target = o3d.geometry.PointCloud(source)
    target.transform(T)
    return source, target, T


def test_the_lean_baseline_polishes_on_clouds_thinned_to_half_the_voxel(monkeypatch):
    source, target, T = _dense_pair()
    seen = []
    refine = tutorial.point_to_plane_refinement

    def recorded(s, t, voxel_size, init, *args):
        seen.append((len(s.points), len(t.points), t.has_normals()))
        return refine(s, t, voxel_size, init, *args)

    monkeypatch.setattr(tutorial, "point_to_plane_refinement", recorded)
    estimate, _ = get_method("fpfh_ransac_lean")(source, target, VOXEL, 0)
    half = len(source.voxel_down_sample(VOXEL / 2).points)
    assert seen == [(half, len(target.voxel_down_sample(VOXEL / 2).points), True)]
    assert half < len(source.points) / 2
    assert rotation_error(estimate, T) < 1.0
    assert translation_error(estimate, T, center=source.get_center()) < 0.002
    assert not target.has_normals()  # the caller's cloud untouched
    assert method_settings("fpfh_ransac_lean")["refinement"]["down_sample_voxels"] == 0.5


def test_the_tutorial_baseline_still_polishes_on_the_full_clouds(monkeypatch):
    source, target, _ = _dense_pair()
    seen = []
    refine = tutorial.point_to_plane_refinement

    def recorded(s, t, voxel_size, init, *args):
        seen.append((len(s.points), len(t.points)))
        return refine(s, t, voxel_size, init, *args)

    monkeypatch.setattr(tutorial, "point_to_plane_refinement", recorded)
    get_method("fpfh_ransac")(source, target, VOXEL, 0)
    assert seen == [(len(source.points), len(target.points))]
