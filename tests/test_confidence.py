"""The calibrated confidence (o3d_spectral.evidence.pose, o3d_spectral.evidence.confidence)
and the ambiguity report (o3d_spectral.evidence.verification.ambiguity), through both calls."""

import json
from pathlib import Path

import numpy as np
import open3d as o3d
import pytest

import o3d_spectral
from o3d_spectral.evidence import confidence as confidence_model
from o3d_spectral.evidence.free_motions import SUPPORT_FLOOR
from o3d_spectral.evidence.pose import PoseEvidence, motion_support, pose_evidence
from o3d_spectral.harness.errors import symmetric_rotation_error, symmetric_translation_error
from o3d_spectral.harness.metrics import instance_score
from o3d_spectral.spectra import so3
from o3d_spectral.synthetic.sampling import model_cloud, point_cloud, rigid
from o3d_spectral.synthetic.scenes import make_instance
from o3d_spectral.synthetic.symmetry import model_symmetry
from o3d_spectral.synthetic.turntable import turntable_pair
from tests.conftest import sample_model

VOXEL = 0.008
ROOT = Path(__file__).resolve().parents[1]


def turned(cloud, angle_deg, axis, shift=(0.0, 0.0, 0.0)):
    T = rigid(so3.exp(np.deg2rad(angle_deg) * np.asarray(axis, float) / np.linalg.norm(axis)),
              np.asarray(shift, float))
    return o3d.geometry.PointCloud(cloud).transform(T), T


def mesh_cloud(mesh, n=3000):
    """Points sampled on ``mesh`` with its outward triangle normals (seeded)."""
    mesh.compute_triangle_normals()
    o3d.utility.random.seed(0)
    return mesh.sample_points_poisson_disk(n, use_triangle_normal=True)


def may_be_wrong(result):
    return [w for w in result.warnings if "may be wrong" in w]


def ambiguous(result):
    return [w for w in result.warnings if w.startswith("ambiguous:")]


def symmetric_twins(result):
    return [n for n in result.notes if n.startswith("symmetric:")]


def test_the_free_space_test_sees_a_surface_in_front_of_what_the_sensor_saw():
    """A plane seen from the origin at 0.5 m: a copy 5 cm nearer the sensor lies where it
    saw through; a copy 5 cm behind it is hidden (no violation); without a sensor the
    test is not made."""
    def plane(half_width):
        grid = np.stack(np.meshgrid(*[np.arange(-half_width, half_width + 1e-9, 0.005)] * 2),
                        axis=-1).reshape(-1, 2)
        points = np.c_[grid, np.full(len(grid), 0.5)]
        return points, np.tile([0.0, 0.0, -1.0], (len(points), 1))  # facing the sensor

    seen, seen_normals = plane(0.15)  # the target: wider than the source's shadow on it
    source, normals = plane(0.1)
    sensor = np.zeros(3)
    nearer, behind = rigid(np.eye(3), [0, 0, -0.05]), rigid(np.eye(3), [0, 0, 0.05])

    def evidence(pose, with_sensor=True):
        return pose_evidence(source, normals, seen, seen_normals, pose, VOXEL, fit=0.0,
                             sensor=sensor if with_sensor else None)

    front, back, right = evidence(nearer), evidence(behind), evidence(np.eye(4))
    unknown = evidence(nearer, with_sensor=False)
    assert front.free_space == 1.0 and back.free_space == 0.0 and right.free_space == 0.0
    assert unknown.free_space is None
    assert right.plane_distance < 0.01 and right.normal_agreement == 1.0
    assert right.target_fit < 1.0  # the wider target is not all explained by the source


def mug_like(rng):
    """A cylinder's side (radius 4 cm, 10 cm tall, axis z) and a small flat tab on it
    (its handle: 6% of the points), with unit normals; the tab's mask."""
    side = rng.uniform([0.0, -0.05], [2.0 * np.pi, 0.05], size=(2000, 2))
    radial = np.c_[np.cos(side[:, 0]), np.sin(side[:, 0]), np.zeros(len(side))]
    body = np.c_[0.04 * radial[:, :2], side[:, 1]]
    tab = np.c_[rng.uniform(0.04, 0.07, 128), np.zeros(128), rng.uniform(-0.02, 0.02, 128)]
    tab_normals = np.tile([0.0, 1.0, 0.0], (128, 1))
    return (np.r_[body, tab], np.r_[radial, tab_normals],
            np.r_[np.zeros(len(body), bool), np.ones(128, bool)])


def test_the_motion_support_is_the_inliers_least_share_of_a_motions_constraint():
    """Every point an inlier: 1. A mug-like cloud's body matched and its tab missed: only
    the tab resists the turn about the axis, and the share is a few floors though 94% of
    the points are inliers. Half the points at random: about a half on every motion. The
    support depends on neither the frame nor the units."""
    points, normals, tab = mug_like(np.random.default_rng(0))
    assert motion_support(points, normals, np.ones(len(points), bool)) == pytest.approx(1.0)
    missed = motion_support(points, normals, ~tab)
    assert SUPPORT_FLOOR < missed < 5 * SUPPORT_FLOOR
    # the turn about the body's axis moves the body along itself: the tab alone resists it
    turn = np.cross(np.array([0.0, 0.0, 1.0]), points)
    resisted = np.abs(np.einsum("ij,ij->i", turn, normals)) > 1e-9
    assert set(np.flatnonzero(resisted)) <= set(np.flatnonzero(tab))
    half = np.random.default_rng(1).random(len(points)) < 0.5  # every motion about half
    assert motion_support(points, normals, half) == pytest.approx(0.5, abs=0.08)
    motion = rigid(so3.exp(np.array([0.3, -1.2, 0.8])), np.array([0.5, -2.0, 1.0]))
    moved = 100.0 * (points @ motion[:3, :3].T + motion[:3, 3])  # centimetres, elsewhere
    assert motion_support(moved, normals @ motion[:3, :3].T, ~tab) == pytest.approx(missed)


def test_a_pose_no_point_corroborates_has_no_support_and_no_confidence():
    """Between two views the model reads a small fit as a small overlap; a fit of 0 (no
    point within a voxel, the target's sensor known and the other evidence at its most
    favourable) is no evidence at all."""
    favourable = PoseEvidence(0.0, 1.0, 0.01, 1.0, 0.0, two_views=True, motion_support=1.0)
    assert confidence_model.probability(confidence_model.features(favourable)) > 0.99
    assert confidence_model.confidence(favourable) == 0.0
    points, normals, _ = mug_like(np.random.default_rng(0))
    # around a copy twice its size (target points near, none within a voxel), or far away
    for target, shift in ((2.0 * points, 0.0), (points, 5.0)):
        pose = rigid(np.eye(3), np.array([shift, 0.0, 0.0]))
        evidence = pose_evidence(points, normals, target, normals, pose, 0.005, fit=0.0,
                                 two_views=True)
        assert evidence.motion_support < 2 * SUPPORT_FLOOR, evidence
        assert confidence_model.confidence(evidence) == 0.0


def test_an_unknown_sensor_leaves_the_free_space_feature_neutral():
    evidence = PoseEvidence(0.9, 0.8, 0.1, 0.9, None)
    values = confidence_model.features(evidence)
    assert values["sqrt_free_space"] == 0.0 and values["sensor_known"] == 0.0
    seen = confidence_model.features(PoseEvidence(0.9, 0.8, 0.1, 0.9, 0.25))
    assert seen["sqrt_free_space"] == 0.5 and seen["sensor_known"] == 1.0


def test_the_coefficients_are_the_stored_calibrations():
    """The library's constants are those the calibration script fitted and stored."""
    stored = json.loads((ROOT / "docs" / "data" / "calibrate_confidence_coefficients.json")
                        .read_text())
    assert stored["bias"] == pytest.approx(confidence_model.BIAS, abs=1e-4)
    for name in confidence_model.FEATURES:
        assert stored[name] == pytest.approx(confidence_model.COEFFICIENTS[name], abs=1e-4)


@pytest.fixture(scope="module")
def drill_view():
    return make_instance("partial", "power_drill", rng=np.random.default_rng(7))


def test_a_right_pose_on_a_clean_view_is_confident(drill_view):
    right = o3d_spectral.registration_spectral_global(drill_view.source, drill_view.target,
                                                      VOXEL)
    assert right.confidence > 0.8 and not may_be_wrong(right)
    assert right.pose_evidence.free_space == 0.0  # the view's sensor was located


@pytest.mark.parametrize("name", ["mug", "cracker_box", "tomato_soup_can"])
def test_another_object_on_the_view_is_warned(drill_view, name):
    """Every pose of another model on the drill's view is wrong."""
    other = point_cloud(*(a.copy() for a in model_cloud(name, 6000)))
    wrong = o3d_spectral.registration_spectral_global(other, drill_view.target, VOXEL)
    assert wrong.confidence < confidence_model.WARN_BELOW
    assert len(may_be_wrong(wrong)) == 1


@pytest.mark.parametrize("name", ["power_drill", "mustard_bottle", "banana", "cracker_box",
                                  "mug"])
def test_a_right_pose_on_a_half_cropped_copy_is_not_warned(name):
    """A crop hides no surface: the half the target lacks is not held against the pose,
    and its cut is not read as free space."""
    points, normals = (a.copy() for a in model_cloud(name, 6000))
    along = (points - points.mean(axis=0)) @ np.array([0.48, 0.6, 0.64])
    motion = rigid(so3.exp(np.array([0.7, -1.1, 0.4])), np.array([0.05, -0.02, 0.03]))
    keep = along > 0.0
    target = point_cloud(points[keep] @ motion[:3, :3].T + motion[:3, 3],
                         normals[keep] @ motion[:3, :3].T)
    result = o3d_spectral.registration_spectral_global(point_cloud(points, normals), target,
                                                       VOXEL)
    symmetry = model_symmetry(name)
    assert symmetric_rotation_error(result.transformation, motion, symmetry) < 5.0
    assert symmetric_translation_error(result.transformation, motion, symmetry,
                                       center=points.mean(axis=0)) < 0.01
    assert result.confidence >= confidence_model.WARN_BELOW and not may_be_wrong(result)


def test_a_box_turned_half_a_turn_is_right_and_its_twin_a_note():
    """A whole box against itself turned half a turn: the pose half a turn away fits as
    well and is the returned one turned by the box's own symmetry, so both are right: a
    note says so, nothing is warned about."""
    box = mesh_cloud(o3d.geometry.TriangleMesh.create_box(0.10, 0.06, 0.03))
    target, _ = turned(box, 180.0, (0.0, 0.0, 1.0), (0.02, 0.01, 0.0))
    result = o3d_spectral.registration_spectral_global(box, target, VOXEL)
    assert result.ambiguity == pytest.approx(180.0, abs=5.0)
    assert ambiguous(result) == [] and not may_be_wrong(result)
    assert symmetric_twins(result) == [
        "symmetric: a pose 180 deg away fits as well, the source turned onto itself: both "
        "are right (result.ambiguity)"]


@pytest.mark.parametrize("call", ["global", "local"])
def test_the_ambiguous_pose_is_returned_in_the_callers_frame(call):
    """A box far from the origin against itself turned half a turn: the pose that fits as
    well is given as a rigid transformation of the source onto the target, in the
    caller's frame (the local call's from an ``init`` near the truth): ``result.ambiguity``
    degrees from the returned one, and it lays the box onto the target as well as the
    returned pose does."""
    box = mesh_cloud(o3d.geometry.TriangleMesh.create_box(0.10, 0.06, 0.03))
    box.translate((3.0, -2.0, 1.0))
    target, T = turned(box, 180.0, (0.0, 0.0, 1.0), (0.02, 0.01, 0.0))
    if call == "global":
        result = o3d_spectral.registration_spectral_global(box, target, VOXEL)
    else:
        init = T @ rigid(so3.exp(np.deg2rad(4.0) * np.array([0.6, 0.0, 0.8])), np.zeros(3))
        result = o3d_spectral.registration_spectral(box, target, VOXEL, init)
    other = result.ambiguous_transformation
    assert result.ambiguity is not None and other.shape == (4, 4)
    assert np.allclose(other[:3, :3] @ other[:3, :3].T, np.eye(3), atol=1e-9)
    assert np.allclose(other[3], [0.0, 0.0, 0.0, 1.0]) and np.linalg.det(other[:3, :3]) > 0
    between = np.asarray(result.transformation)[:3, :3].T @ other[:3, :3]
    assert np.rad2deg(so3.rotation_angle(between)) == pytest.approx(result.ambiguity, abs=1e-6)
    fits = [o3d.pipelines.registration.evaluate_registration(box, target, VOXEL, M).fitness
            for M in (np.asarray(result.transformation), other)]
    assert fits[1] >= fits[0] - 0.05 and fits[1] > 0.8


def test_an_unambiguous_pose_has_no_ambiguous_transformation():
    source = sample_model("power_drill", 6000)
    target, _ = turned(source, 10.0, (0.0, 0.0, 1.0), (0.01, 0.0, 0.0))
    result = o3d_spectral.registration_spectral(source, target, VOXEL)
    assert result.ambiguity is None and result.ambiguous_transformation is None


@pytest.mark.parametrize("mesh", [
    o3d.geometry.TriangleMesh.create_sphere(0.04, resolution=40),
    o3d.geometry.TriangleMesh.create_cylinder(0.03, 0.12, resolution=40),
], ids=["sphere", "cylinder"])
def test_a_sphere_and_a_cylinder_are_ambiguous_by_their_symmetry(mesh):
    """A whole sphere or cylinder against itself turned: a distinct pose fits as well and
    is the returned one turned by the source's own symmetry: a note, no warning."""
    cloud = mesh_cloud(mesh)
    target, _ = turned(cloud, 66.0, (0.3, 0.2, 1.0), (0.01, 0.0, 0.02))
    result = o3d_spectral.registration_spectral_global(cloud, target, VOXEL)
    assert result.ambiguity is not None and ambiguous(result) == []
    assert len(symmetric_twins(result)) == 1


def test_the_mustard_bottle_turned_20_degrees_is_ambiguous_by_its_symmetry():
    """Its front and back nearly match: a half turn fits as well, whichever is returned,
    and maps the whole model onto itself: a note, no warning."""
    source = sample_model("mustard_bottle", 30000)
    target, _ = turned(source, 20.0, (1.0, 2.0, 3.0))
    result = o3d_spectral.registration_spectral_global(source, target, VOXEL)
    assert result.ambiguity is not None and result.ambiguity > 90.0
    assert ambiguous(result) == [] and len(symmetric_twins(result)) == 1


def test_the_local_call_is_confident_where_it_is_right():
    source = sample_model("power_drill", 6000)
    target, T = turned(source, 10.0, (0.0, 0.0, 1.0), (0.01, 0.0, 0.0))
    result = o3d_spectral.registration_spectral(source, target, VOXEL)
    assert so3.rotation_angle(result.transformation[:3, :3].T @ T[:3, :3]) < np.deg2rad(1.0)
    assert result.confidence > 0.9 and result.ambiguity is None and not result.warnings


@pytest.mark.parametrize("name", ["mug", "tomato_soup_can", "power_drill"])
def test_two_views_90_degrees_apart_are_warned_when_wrong_only(name):
    """A mug's body seen from two sides fits any turn about its axis; where the handle
    misses, the pose is warned (the motion support); a can, symmetric about that axis,
    and a drill, which no turn fits, are not."""
    pair = turntable_pair(name, 90.0, 30.0, np.random.default_rng(7))
    result = o3d_spectral.registration_spectral_global(pair.source, pair.target, VOXEL)
    _, _, right = instance_score(pair)(np.asarray(result.transformation))
    assert bool(may_be_wrong(result)) == (not right)
