"""A source prepared once (o3d_spectral.prepare) gives the results of the cloud itself."""

import numpy as np
import open3d as o3d
import pytest

import o3d_spectral
from o3d_spectral.spectra import so3
from tests.conftest import sample_model

VOXEL = 0.008


@pytest.fixture(scope="module")
def pair():
    source = sample_model("mustard_bottle", 8000)
    T = np.eye(4)
    T[:3, :3] = so3.exp(np.deg2rad(70.0) * np.array([0.0, 0.6, 0.8]))
    T[:3, 3] = [0.02, -0.03, 0.01]
    target = o3d.geometry.PointCloud(source)
    target.transform(T)
    return source, target


@pytest.mark.slow
@pytest.mark.parametrize("call", ["registration_spectral", "registration_spectral_global"])
def test_a_prepared_source_gives_the_same_result(pair, call):
    """Equal to rounding: the registration works in a frame centred on the target, where
    the call moves the prepared cloud, and the cloud itself is prepared after the move."""
    source, target = pair
    register = getattr(o3d_spectral, call)
    plain = register(source, target, VOXEL)
    prepared = register(o3d_spectral.prepare(source, VOXEL), target, VOXEL)
    np.testing.assert_allclose(plain.transformation, prepared.transformation, atol=1e-9)
    assert plain.fitness == pytest.approx(prepared.fitness, abs=1e-6)


@pytest.mark.slow
def test_a_prepared_source_far_from_the_origin_gives_the_same_pose(pair):
    """Clouds far away are registered in a frame centred on the target: the prepared
    cloud is moved there, equal to the cloud's own preparation to rounding."""
    source, target = pair
    far = np.eye(4)
    far[:3, 3] = [150.0, -80.0, 20.0]
    source, target = (o3d.geometry.PointCloud(c).transform(far) for c in (source, target))
    plain = o3d_spectral.registration_spectral_global(source, target, VOXEL)
    prepared = o3d_spectral.registration_spectral_global(
        o3d_spectral.prepare(source, VOXEL), target, VOXEL)
    np.testing.assert_allclose(plain.transformation, prepared.transformation, atol=1e-6)


def test_a_prepared_source_is_reused_unchanged(pair):
    source, target = pair
    ready = o3d_spectral.prepare(source, VOXEL)
    points = ready.cloud.points.copy()
    for _ in range(2):
        o3d_spectral.registration_spectral(ready, target, VOXEL)
    np.testing.assert_array_equal(ready.cloud.points, points)


@pytest.mark.parametrize("settings, field", [
    ({"voxel_size": 0.01}, "voxel_size"),
    ({"option": o3d_spectral.SpectralRegistrationOption(egi_voxel_size=0.001)},
     "egi_voxel_size"),
    ({"cloud": o3d_spectral.CloudOption(normal_radius=0.05)}, "normal_radius"),
    ({"cloud": o3d_spectral.CloudOption(camera_location=(0.0, 0.0, 1.0))}, "camera_location"),
])
def test_settings_other_than_the_preparation_are_refused(pair, settings, field):
    source, target = pair
    ready = o3d_spectral.prepare(source, VOXEL)
    voxel = settings.pop("voxel_size", VOXEL)
    with pytest.raises(ValueError, match=f"source was prepared with {field}"):
        o3d_spectral.registration_spectral(ready, target, voxel, **settings)


def test_prepare_checks_its_arguments(pair):
    source, _ = pair
    with pytest.raises(ValueError, match="voxel_size"):
        o3d_spectral.prepare(source, -1.0)
    with pytest.raises(TypeError, match="option"):
        o3d_spectral.prepare(source, VOXEL, option="fast")
    with pytest.raises(TypeError, match="source"):
        o3d_spectral.prepare("model.ply", VOXEL)


def test_a_prepared_source_cannot_be_edited(pair):
    """Its arrays are not writeable: an edit would move every later result."""
    ready = o3d_spectral.prepare(pair[0], VOXEL)
    for array in (ready.cloud.points, ready.cloud.normals, ready.cloud.point_normals,
                  ready.cloud.normal_points):
        with pytest.raises(ValueError, match="read-only"):
            array[0, 0] = 1.0
