"""A target prepared once (o3d_spectral.prepare_target) gives the results of the cloud
itself, call after call."""

import numpy as np
import open3d as o3d
import pytest

import o3d_spectral
from o3d_spectral.synthetic.scenes import make_instance
from o3d_spectral.synthetic.suite import instance_rng
from tests.conftest import sample_model

VOXEL = 0.008


@pytest.fixture(scope="module")
def scene():
    """A partial view of a power drill (a single view: culling, sensor found) and its model."""
    instance = make_instance("partial", "power_drill", rng=instance_rng(0, 2))
    return instance.source, instance.target


@pytest.mark.parametrize("call", ["registration_spectral", "registration_spectral_global"])
def test_a_prepared_target_gives_the_same_result_to_the_bit(scene, call):
    source, target = scene
    register = getattr(o3d_spectral, call)
    plain = register(source, target, VOXEL)
    ready = o3d_spectral.prepare_target(target, VOXEL)
    for _ in range(2):  # and again: what the first call cached changes nothing
        prepared = register(source, ready, VOXEL)
        np.testing.assert_array_equal(plain.transformation, prepared.transformation)
        assert plain.fitness == prepared.fitness and plain.fit == prepared.fit
        np.testing.assert_array_equal(np.asarray(plain.correspondence_set),
                                      np.asarray(prepared.correspondence_set))


def test_a_prepared_target_far_from_the_origin_gives_the_same_pose(scene):
    source, target = scene
    far = np.eye(4)
    far[:3, 3] = [150.0, -80.0, 20.0]
    source, target = (o3d.geometry.PointCloud(c).transform(far) for c in (source, target))
    plain = o3d_spectral.registration_spectral_global(source, target, VOXEL)
    prepared = o3d_spectral.registration_spectral_global(
        source, o3d_spectral.prepare_target(target, VOXEL), VOXEL)
    np.testing.assert_array_equal(plain.transformation, prepared.transformation)


def test_a_prepared_target_refuses_other_settings_by_name(scene):
    source, target = scene
    ready = o3d_spectral.prepare_target(target, VOXEL)
    with pytest.raises(ValueError, match="target was prepared with voxel_size"):
        o3d_spectral.registration_spectral_global(source, ready, 0.01)
    with pytest.raises(ValueError, match="target was prepared with option"):
        o3d_spectral.registration_spectral(
            source, ready, VOXEL, option=o3d_spectral.SpectralRegistrationOption(bandwidth=8))
    with pytest.raises(ValueError, match="target was prepared with cloud"):
        o3d_spectral.registration_spectral(
            source, ready, VOXEL, cloud=o3d_spectral.CloudOption(normal_radius=0.02))


def test_prepare_target_leaves_the_cloud_alone_and_keeps_a_copy():
    target = sample_model("mug", 3000)
    points = np.asarray(target.points).copy()
    ready = o3d_spectral.prepare_target(target, VOXEL)
    np.asarray(target.points)[0] += 1.0  # the caller's edit after the preparation ...
    np.testing.assert_array_equal(ready.arrays.points, points)  # ... does not reach it
    with pytest.raises(TypeError, match="voxel_size"):
        o3d_spectral.prepare_target(target, "0.008")
