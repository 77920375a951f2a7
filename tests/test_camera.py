"""Virtual depth camera: geometry of the rays, noise model, normals and labels."""

import numpy as np
import open3d as o3d
import pytest
from numpy.testing import assert_allclose

from o3d_spectral.synthetic.camera import (
    hit_labels,
    look_at,
    render,
    scan_from_view,
    scan_meshes,
)
from o3d_spectral.synthetic.models import load_model
from o3d_spectral.synthetic.sensor import CameraIntrinsics, DepthNoise


@pytest.fixture(scope="module")
def mustard():
    return load_model("mustard_bottle")


def _pose_facing(mesh, distance=0.6):
    center = np.asarray(mesh.get_center())
    return look_at(center + [0.0, -distance, 0.1], center)


def test_default_intrinsics_are_640x480_60_degrees():
    intr = CameraIntrinsics()
    assert (intr.width, intr.height) == (640, 480)
    assert_allclose(2 * np.arctan(intr.width / 2 / intr.fx), np.deg2rad(60))
    assert_allclose(CameraIntrinsics.from_fov(fov=np.deg2rad(60)).matrix, intr.matrix)


@pytest.mark.parametrize("kwargs", [{"width": 0}, {"fx": -1.0}], ids=["width", "fx"])
def test_intrinsics_reject_bad_values(kwargs):
    with pytest.raises(ValueError, match=next(iter(kwargs))):
        CameraIntrinsics(**kwargs)


def test_look_at_is_a_rigid_pose_looking_at_target():
    pose = look_at([1.0, 2.0, 3.0], [0.0, 0.0, 0.0])
    assert_allclose(pose[:3, :3].T @ pose[:3, :3], np.eye(3), atol=1e-12)
    assert_allclose(np.linalg.det(pose[:3, :3]), 1.0)
    forward = pose[:3, 2]
    assert_allclose(forward, -np.array([1, 2, 3]) / np.sqrt(14))
    with pytest.raises(ValueError, match="up"):
        look_at([0, 0, 1], [0, 0, 0], up=[0, 0, 1])


def test_noiseless_points_lie_on_the_mesh(mustard):
    pose = _pose_facing(mustard)
    scan = scan_meshes(
        [mustard],
        CameraIntrinsics(),
        pose,
        noise=DepthNoise.noiseless(),
        rng=np.random.default_rng(0),
    )
    assert len(scan.points) > 1000
    world = scan.points @ pose[:3, :3].T + pose[:3, 3]
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(mustard))
    distance = scene.compute_distance(o3d.core.Tensor(world.astype(np.float32))).numpy()
    assert distance.max() < 1e-5  # float32 ray casting


def test_points_project_back_to_their_pixels(mustard):
    intr = CameraIntrinsics()
    scan = scan_meshes([mustard], intr, _pose_facing(mustard), rng=np.random.default_rng(1))
    assert_allclose(intr.project(scan.points), scan.pixels[:, ::-1], atol=1e-9)


def test_normals_face_the_camera_and_are_unit(mustard):
    scan = scan_meshes(
        [mustard], CameraIntrinsics(), _pose_facing(mustard), rng=np.random.default_rng(2)
    )
    assert_allclose(np.linalg.norm(scan.normals, axis=1), 1.0, atol=1e-6)
    assert np.all(np.einsum("ij,ij->i", scan.normals, scan.points) < 0)


def test_noise_matches_the_model_and_respects_the_range():
    noise = DepthNoise(disparity_step=0.0)
    depth = np.full(20000, 1.5)
    noisy = noise.apply(depth, fx=500.0, rng=np.random.default_rng(3))
    assert_allclose(np.std(noisy - depth), noise.sigma(1.5), rtol=0.05)
    assert np.isnan(noise.apply(np.array([0.1, 3.5]), fx=500.0, rng=np.random.default_rng(0))).all()


def test_quantisation_steps_grow_with_depth():
    noise = DepthNoise(sigma_0=0.0, sigma_quadratic=0.0)
    fx = CameraIntrinsics().fx
    for z in (0.5, 1.0, 2.0):
        levels = np.unique(
            noise.apply(np.linspace(z, z + 0.05, 2000), fx=fx, rng=np.random.default_rng(0))
        )
        step = np.median(np.diff(levels))
        assert_allclose(step, z**2 * noise.disparity_step / (fx * noise.baseline), rtol=0.1)


def test_object_ids_and_hit_labels_agree(mustard):
    bowl = load_model("bowl").translate([0.0, 0.0, 0.3])
    intr = CameraIntrinsics()
    pose = look_at([0.0, -0.8, 0.4], [0.0, 0.0, 0.15])
    view = render([mustard, bowl], intr, pose, labels=[5, -1])
    assert set(np.unique(view.ids)) == {-2, -1, 5}
    pixels = np.argwhere(view.ids > -2)[::7]
    labels = hit_labels([mustard, bowl], intr, pose, pixels=pixels, labels=[5, -1])
    assert_allclose(labels, view.ids[pixels[:, 0], pixels[:, 1]])
    scan = scan_from_view(view, rng=np.random.default_rng(0))
    assert set(np.unique(scan.object_ids)) <= {-1, 5}


def test_same_seed_same_scan(mustard):
    pose = _pose_facing(mustard)
    a = scan_meshes([mustard], CameraIntrinsics(), pose, rng=np.random.default_rng(7))
    b = scan_meshes([mustard], CameraIntrinsics(), pose, rng=np.random.default_rng(7))
    assert np.array_equal(a.points, b.points)


def test_render_rejects_mismatched_labels(mustard):
    with pytest.raises(ValueError, match="labels"):
        render([mustard], CameraIntrinsics(), np.eye(4), labels=[0, 1])
