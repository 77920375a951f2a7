"""Two depth views of a model on a turntable (o3d_spectral.synthetic.turntable)."""

import numpy as np
import open3d as o3d
import pytest

from o3d_spectral.synthetic.turntable import DISTANCE, turntable_pair


@pytest.mark.parametrize("angle", [45.0, 135.0])
def test_the_truth_maps_the_first_view_onto_the_second_where_they_overlap(angle):
    pair = turntable_pair("power_drill", angle, 30.0, np.random.default_rng(3))
    moved = o3d.geometry.PointCloud(pair.source)
    moved.transform(pair.T_gt)
    distances = np.asarray(moved.compute_point_cloud_distance(pair.target))
    assert np.percentile(distances, 20) < 0.002  # the shared surface, within the noise
    R = pair.T_gt[:3, :3]
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    turned = np.rad2deg(np.arccos(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)))
    assert turned == pytest.approx(angle, abs=1e-6)  # the cameras turn about the table's axis


def test_each_view_is_in_its_own_camera_frame_facing_its_camera():
    pair = turntable_pair("mustard_bottle", 90.0, 45.0, np.random.default_rng(0))
    for cloud in (pair.source, pair.target):
        points, normals = np.asarray(cloud.points), np.asarray(cloud.normals)
        assert np.all(points[:, 2] > 0.0)
        assert abs(np.linalg.norm(points.mean(axis=0)) - DISTANCE) < 0.1
        assert np.all(np.einsum("ij,ij->i", normals, -points) >= 0.0)


def test_a_pair_is_the_same_for_the_same_seed_and_its_symmetry_follows_the_view():
    a = turntable_pair("tomato_soup_can", 60.0, 20.0, np.random.default_rng(7))
    b = turntable_pair("tomato_soup_can", 60.0, 20.0, np.random.default_rng(7))
    np.testing.assert_array_equal(np.asarray(a.source.points), np.asarray(b.source.points))
    np.testing.assert_array_equal(a.T_gt, b.T_gt)
    assert a.metadata["angle_deg"] == 60.0 and a.object == "tomato_soup_can"
    assert a.symmetry.axis is not None  # a can: any turn about its axis
