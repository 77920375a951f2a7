"""Symmetry groups of the models and the (symmetric) pose errors."""

import numpy as np
import open3d as o3d
import pytest
from numpy.testing import assert_allclose
from scipy.spatial.transform import Rotation

from o3d_spectral.harness.errors import (
    mssd,
    rotation_error,
    symmetric_rotation_error,
    symmetric_translation_error,
    translation_error,
)
from o3d_spectral.synthetic.models import load_model, model_names
from o3d_spectral.synthetic.symmetry import (
    SYMMETRIC_MODELS,
    Symmetry,
    model_symmetry,
    refine_axis,
)


def _pose(rotvec, t):
    m = np.eye(4)
    m[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    m[:3, 3] = t
    return m


def test_plain_errors():
    a = _pose([0, 0, np.deg2rad(30)], [0.1, 0, 0])
    b = _pose([0, 0, 0], [0, 0.2, 0])
    assert_allclose(rotation_error(a, b), 30.0)
    assert_allclose(rotation_error(a[:3, :3], b[:3, :3]), 30.0)
    assert_allclose(translation_error(a, b), np.hypot(0.1, 0.2))
    assert rotation_error(b, b) == 0.0
    assert_allclose(rotation_error(_pose([np.pi, 0, 0], [0, 0, 0]), np.eye(4)), 180.0)


def test_errors_reject_bad_shapes():
    with pytest.raises(ValueError, match="T_est"):
        rotation_error(np.eye(2), np.eye(3))
    with pytest.raises(ValueError, match="T_gt"):
        translation_error(np.eye(4), np.eye(3))


@pytest.mark.parametrize("name", model_names())
def test_recorded_symmetries_map_the_mesh_onto_itself(name):
    mesh = load_model(name)
    symmetry = model_symmetry(name)
    assert (name in SYMMETRIC_MODELS) != symmetry.is_trivial
    o3d.utility.random.seed(0)
    points = np.asarray(mesh.sample_points_uniformly(2000).points)
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(mesh))
    for s in symmetry.elements(step=np.deg2rad(45)):
        moved = (points @ s[:3, :3].T + s[:3, 3]).astype(np.float32)
        assert scene.compute_distance(o3d.core.Tensor(moved)).numpy().mean() < 0.002


def _surface(mesh, pose, n=20000):
    """``n`` seeded samples of ``mesh`` moved by ``pose``, with their normals."""
    o3d.utility.random.seed(0)
    cloud = mesh.sample_points_uniformly(n, use_triangle_normal=True)
    return cloud.transform(pose)


def _tilted(axis, degrees, seed):
    """``axis`` turned by ``degrees`` about a random perpendicular direction."""
    rng = np.random.default_rng(seed)
    side = np.cross(axis, rng.normal(size=3))
    return Rotation.from_rotvec(np.deg2rad(degrees) * side / np.linalg.norm(side)).apply(axis)


@pytest.mark.parametrize("seed", range(3))
def test_refine_axis_recovers_a_box_face_normal(seed):
    """A 180-degree turn about a box's face normal maps it onto itself: started 3 degrees
    and 2 mm off, the refinement finds that normal and a point of its line."""
    pose = _pose(Rotation.random(random_state=seed).as_rotvec(), [0.1, -0.2, 0.5])
    box = o3d.geometry.TriangleMesh.create_box(0.05, 0.06, 0.08).translate([-0.025, -0.03, -0.04])
    cloud = _surface(box, pose)
    normal, centre = pose[:3, 1], pose[:3, 3]
    start = centre + 0.002 * pose[:3, 0]
    axis, point = refine_axis(cloud, _tilted(normal, 3.0, seed), np.pi, start)
    assert np.rad2deg(np.arccos(min(1.0, axis @ normal))) < 0.1
    offset = point - centre
    assert np.linalg.norm(offset - (offset @ normal) * normal) < 1e-4


def test_refine_axis_recovers_a_cylinder_axis():
    """A continuous axis, refined through a quarter turn about it."""
    pose = _pose([0.3, -0.5, 0.2], [0.0, 0.1, 0.6])
    cylinder = o3d.geometry.TriangleMesh.create_cylinder(0.04, 0.1, resolution=120, split=8)
    cloud = _surface(cylinder, pose)
    true_axis, centre = pose[:3, 2], pose[:3, 3]
    axis, point = refine_axis(cloud, _tilted(true_axis, 3.0, 1), np.pi / 2, centre)
    assert np.rad2deg(np.arccos(min(1.0, axis @ true_axis))) < 0.1
    offset = point - centre
    assert np.linalg.norm(offset - (offset @ true_axis) * true_axis) < 1e-4


def _random_case(seed, symmetry):
    rng = np.random.default_rng(seed)
    t_gt = _pose(Rotation.random(random_state=rng).as_rotvec(), rng.normal(size=3) * 0.1)
    t_est = _pose(Rotation.random(random_state=rng).as_rotvec(), rng.normal(size=3) * 0.1)
    frame = _pose(Rotation.random(random_state=rng).as_rotvec(), rng.normal(size=3))
    return t_est, t_gt, symmetry.transformed(frame)


@pytest.mark.parametrize("name", ["master_chef_can", "bowl", "cracker_box"])
@pytest.mark.parametrize("seed", range(4))
def test_analytic_minimum_matches_fine_sampling(name, seed):
    t_est, t_gt, sym = _random_case(seed, model_symmetry(name))
    group = t_gt @ sym.elements(step=np.deg2rad(0.05))
    sampled_r = min(rotation_error(t_est, g) for g in group)
    sampled_t = min(translation_error(t_est, g) for g in group)
    assert_allclose(symmetric_rotation_error(t_est, t_gt, sym), sampled_r, atol=0.05)
    assert_allclose(symmetric_translation_error(t_est, t_gt, sym), sampled_t, atol=1e-4)
    assert symmetric_rotation_error(t_est, t_gt, sym) <= rotation_error(t_est, t_gt) + 1e-9


@pytest.mark.parametrize("name", ["tomato_soup_can", "gelatin_box", "foam_brick"])
def test_symmetric_errors_vanish_on_equivalent_poses(name):
    rng = np.random.default_rng(0)
    sym = model_symmetry(name)
    t_gt = _pose(Rotation.random(random_state=rng).as_rotvec(), [0.1, 0.2, 0.3])
    element = sym.elements(step=np.deg2rad(37))[-1]
    t_est = t_gt @ element
    assert rotation_error(t_est, t_gt) > 1.0
    assert symmetric_rotation_error(t_est, t_gt, sym) < 1e-5
    assert symmetric_translation_error(t_est, t_gt, sym) < 1e-9
    points = np.asarray(load_model(name).vertices)
    assert mssd(t_est, t_gt, points, sym, step=np.deg2rad(37)) < 1e-9
    assert mssd(t_est, t_gt, points) > 0.01


def test_trivial_symmetry_gives_plain_errors():
    t_est, t_gt, sym = _random_case(9, Symmetry())
    assert_allclose(symmetric_rotation_error(t_est, t_gt, sym), rotation_error(t_est, t_gt))
    assert_allclose(symmetric_translation_error(t_est, t_gt, sym), translation_error(t_est, t_gt))


def test_unknown_model_is_rejected():
    with pytest.raises(ValueError, match="unknown model"):
        model_symmetry("teapot")


def test_translation_error_at_a_centre_ignores_the_lever_arm():
    """A rotation about the object's centroid moves the centroid nowhere: zero error there,
    though the source frame's origin (1 m away) moves by 2 sin(angle/2) m."""
    from o3d_spectral.spectra import so3

    center = np.array([0.0, 0.0, 1.0])
    T_gt = np.eye(4)
    T_gt[:3, 3] = [0.1, 0.2, 0.3]
    turn = np.eye(4)
    turn[:3, :3] = so3.exp([0.0, 0.05, 0.0])
    turn[:3, 3] = center - turn[:3, :3] @ center
    T_est = T_gt @ turn
    assert translation_error(T_est, T_gt) == pytest.approx(2 * np.sin(0.025))
    assert translation_error(T_est, T_gt, center=center) == pytest.approx(0.0, abs=1e-15)
    assert symmetric_translation_error(T_est, T_gt, Symmetry(), center=center) == pytest.approx(
        0.0, abs=1e-15
    )
