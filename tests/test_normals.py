"""Normals: sign checks, orientation, and single views recognised in any frame
(o3d_spectral.io.normals), checked on exact shapes and on the bundled real scans."""

from __future__ import annotations

import logging

import numpy as np
import open3d as o3d
import pytest
from scipy.spatial.transform import Rotation

import o3d_spectral
from o3d_spectral.harness.errors import (
    rotation_error,
    symmetric_translation_error,
    translation_error,
)
from o3d_spectral.harness.real import load_cases
from o3d_spectral.io.cloud import as_arrays, prepare
from o3d_spectral.io.normals import orient, sensor_direction, view_direction
from o3d_spectral.io.signs import SIGN_DISAGREEMENT, THIN_WALLS, back_to_back, sign_disagreement
from tests.conftest import thin_walled_cup

VOXEL = 0.008


def _sphere(n: int = 4000, radius: float = 0.05, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(n, 3))
    return u / np.linalg.norm(u, axis=1, keepdims=True) * radius


def _world(degrees=(30.0, -50.0, 80.0)) -> np.ndarray:
    W = np.eye(4)
    W[:3, :3] = Rotation.from_euler("xyz", degrees, degrees=True).as_matrix()
    return W


def _crop(name: str):
    return next(c for c in load_cases(["ycbv_crop"]) if c.name == f"ycbv_crop_{name}")


def _in_world_frame(case):
    """The crop moved so that the world origin is inside its bounding box; the motion."""
    W = _world()
    centre = np.asarray(case.target.points).mean(axis=0)
    W[:3, 3] = -W[:3, :3] @ centre + [0.01, -0.02, 0.005]
    return o3d.geometry.PointCloud(case.target).transform(W), W


def test_consistent_normals_agree_and_random_signs_do_not():
    points = _sphere()
    outward = points / np.linalg.norm(points, axis=1, keepdims=True)
    signs = np.random.default_rng(1).choice([-1.0, 1.0], size=(len(points), 1))
    assert sign_disagreement(points, outward) == 0.0
    assert sign_disagreement(points, outward * signs) > 0.3


def test_open3d_unoriented_estimate_on_a_real_scan_is_caught():
    scan = o3d.geometry.PointCloud(load_cases(["dragon_24"])[0].source)
    scan.estimate_normals()  # Open3D's default: no orientation step
    points, normals = np.asarray(scan.points), np.asarray(scan.normals)
    assert sign_disagreement(points, normals) > SIGN_DISAGREEMENT
    scan.orient_normals_towards_camera_location([0.0, 0.0, 10.0])
    assert sign_disagreement(points, np.asarray(scan.normals)) < SIGN_DISAGREEMENT


def test_thin_walls_disagree_back_to_back_and_unoriented_signs_do_not():
    """A cup's wall 2 mm thick sampled 3000 times: neighbours lie on either face, with
    normals pointing away from each other. Random signs on one surface (the cup's outer
    face, a sphere) disagree as often, but not back to back."""
    points, normals = thin_walled_cup(wall=0.002)
    assert sign_disagreement(points, normals) > SIGN_DISAGREEMENT
    assert back_to_back(points, normals) >= THIN_WALLS
    outer = (normals[:, 2] == 0.0) & (np.einsum("ij,ij->i", points, normals) > 0.0)
    for p, n in ((points[outer], normals[outer]), (_sphere(), _sphere() / 0.05)):
        random = n * np.random.default_rng(4).choice([-1.0, 1.0], size=(len(n), 1))
        assert sign_disagreement(p, random) > 0.3
        assert back_to_back(p, random) < 0.5 * THIN_WALLS


def test_a_thin_walled_cloud_is_read_two_sided_and_others_are_not():
    """Thin walls: two-sided, normals as given (their signs unused), no view. A closed
    sphere with outward normals is read as given, one-sided; with random signs, and the
    cup's outer face with random signs, they are oriented again, one-sided."""
    cup = prepare(as_arrays(np.hstack(thin_walled_cup(wall=0.002))), VOXEL)
    assert cup.reading.two_sided
    assert (cup.reading.normals_from, cup.reading.orientation) == ("given", None)
    assert cup.reading.view is None
    points = _sphere()
    outward = points / 0.05
    signs = np.random.default_rng(5).choice([-1.0, 1.0], size=(len(points), 1))
    sphere = prepare(as_arrays(np.hstack([points, outward])), VOXEL).reading
    assert not sphere.two_sided and sphere.normals_from == "given"
    shuffled = prepare(as_arrays(np.hstack([points, outward * signs])), VOXEL).reading
    assert not shuffled.two_sided and shuffled.normals_from == "re-oriented"
    p, n = thin_walled_cup(wall=0.002)
    outer = (n[:, 2] == 0.0) & (np.einsum("ij,ij->i", p, n) > 0.0)
    flipped = n[outer] * np.random.default_rng(6).choice([-1.0, 1.0], size=(outer.sum(), 1))
    face = prepare(as_arrays(np.hstack([p[outer], flipped])), VOXEL)
    assert not face.reading.two_sided and face.reading.normals_from == "re-oriented"


def test_normals_facing_the_sensor_are_taken_as_given_without_the_neighbour_search():
    """A depth camera's view in its own frame (the near cap of a sphere 0.5 m in front
    of the origin, outward normals): every normal faces the sensor, so the signs are
    used as given and the neighbour search is skipped (disagreement not measured). With
    a third of the signs flipped they no longer all face it: searched, and re-oriented."""
    points = _sphere(radius=0.1)
    near = points[points[:, 2] < -0.07]  # the cap the camera sees, not its rim
    outward = near / 0.1
    view = near + [0.0, 0.0, 0.5]
    reading = prepare(as_arrays(np.hstack([view, outward])), VOXEL).reading
    assert (reading.normals_from, reading.sign_disagreement) == ("given", None)
    signs = np.where(np.random.default_rng(7).random((len(near), 1)) < 0.33, -1.0, 1.0)
    flipped = prepare(as_arrays(np.hstack([view, outward * signs])), VOXEL).reading
    assert flipped.normals_from == "re-oriented"
    assert flipped.sign_disagreement > SIGN_DISAGREEMENT


def test_orient_towards_a_camera_and_outward_on_a_model():
    points = _sphere()
    outward = points / np.linalg.norm(points, axis=1, keepdims=True)
    signs = np.random.default_rng(2).choice([-1.0, 1.0], size=(len(points), 1))
    camera = np.array([0.0, 0.0, 1.0])
    toward, rule = orient(points, outward * signs, VOXEL, camera_location=camera)
    assert rule == "camera"
    assert np.all(np.einsum("ij,ij->i", toward, camera - points) >= 0.0)
    model, rule = orient(points, outward * signs, VOXEL)
    assert rule == "surface"
    assert np.mean(np.einsum("ij,ij->i", model, outward) > 0.0) > 0.99


def test_a_closed_surface_is_no_view_and_a_cap_seen_from_afar_is():
    points = _sphere()
    outward = points / np.linalg.norm(points, axis=1, keepdims=True)
    assert view_direction(points, outward, VOXEL) is None
    assert sensor_direction(points, outward, VOXEL) is None
    d = np.array([0.3, -0.2, 0.9]) / np.linalg.norm([0.3, -0.2, 0.9])
    cap = outward @ d > 0.2  # what a distant sensor in direction d sees of it
    found = view_direction(points[cap], outward[cap], VOXEL)
    assert found is not None and np.degrees(np.arccos(found @ d)) < 10.0


@pytest.mark.parametrize("name", ["009_gelatin_box", "061_foam_brick"])
def test_normals_estimated_on_a_view_in_a_world_frame_face_its_sensor(name):
    world, W = _in_world_frame(_crop(name))
    prepared = prepare(as_arrays(world), VOXEL)
    sensor = W[:3, 3]  # the camera, at the camera frame's origin
    facing = np.einsum("ij,ij->i", prepared.normals, sensor - prepared.normal_points) > 0.0
    assert prepared.reading.orientation == "hemisphere"
    assert prepared.reading.view is not None
    assert facing.mean() >= 0.99


def test_a_view_in_a_world_frame_registers_as_in_its_camera_frame():
    # The foam brick is nearly a cuboid: a 180-degree turn about one of its axes fits the
    # view as well as the truth does (the search says so: low confidence), so the check
    # is the fit and the centroid's place up to the brick's symmetries (as the harness
    # counts a success).
    case = _crop("061_foam_brick")
    world, W = _in_world_frame(case)
    in_camera = o3d_spectral.registration_spectral_global(case.source, case.target, VOXEL)
    in_world = o3d_spectral.registration_spectral_global(case.source, world, VOXEL)
    centre = np.asarray(case.source.points).mean(axis=0)
    for result, truth in ((in_camera, case.T_gt), (in_world, W @ case.T_gt)):
        assert symmetric_translation_error(result.transformation, truth, case.symmetry,
                                           center=centre) < 0.003
        assert result.fitness > 0.7
        assert result.target_viewpoint is not None  # matched as its sensor saw it
    assert abs(in_world.fitness - in_camera.fitness) < 0.05


@pytest.mark.slow
def test_unoriented_normals_are_reoriented_with_a_warning(caplog):
    case = load_cases(["dragon_24"])[0]
    source, target = o3d.geometry.PointCloud(case.source), o3d.geometry.PointCloud(case.target)
    for cloud in (source, target):
        cloud.estimate_normals()
    before = np.asarray(source.normals).copy()
    with caplog.at_level(logging.WARNING, logger="o3d_spectral"):
        result = o3d_spectral.registration_spectral_global(source, target, 0.005)
    assert result.source_reading.normals_from == "re-oriented"
    assert result.target_reading.normals_from == "re-oriented"
    assert any("oriented again" in message for message in caplog.messages)
    assert np.array_equal(np.asarray(source.normals), before)  # the caller's untouched
    centre = np.asarray(case.source.points).mean(axis=0)
    assert rotation_error(result.transformation, case.T_gt) < 5.0
    assert translation_error(result.transformation, case.T_gt, center=centre) < 0.01


@pytest.mark.slow
def test_two_views_are_matched_whole():
    case = load_cases(["dragon_24"])[0]
    result = o3d_spectral.registration_spectral(case.source, case.target, 0.005, case.T_gt)
    assert result.source_reading.view is not None and result.target_reading.view is not None
    assert result.target_viewpoint is None


@pytest.mark.slow
def test_a_plane_and_a_run_cut_short_each_log_a_warning(caplog):
    rng = np.random.default_rng(3)
    plane = np.c_[rng.uniform(-0.1, 0.1, (3000, 2)), np.zeros(3000)]
    with caplog.at_level(logging.WARNING, logger="o3d_spectral"):
        result = o3d_spectral.registration_spectral(plane, plane, VOXEL)
    assert any("nearly all alike" in message for message in result.warnings)
    assert any("nearly all alike" in message for message in caplog.messages)
    caplog.clear()
    bowl = _sphere()
    bowl = bowl[bowl[:, 2] < 0.02]
    short = o3d_spectral.SpectralConvergenceCriteria(max_iteration=1)
    with caplog.at_level(logging.WARNING, logger="o3d_spectral"):
        result = o3d_spectral.registration_spectral(bowl, bowl + [0.01, 0.0, 0.0], VOXEL,
                                                    criteria=short)
    assert not result.converged
    assert any("max_iteration=1" in message for message in caplog.messages)


@pytest.mark.parametrize("angle", [0, 72, 144])
def test_a_scan_whose_frame_origin_lies_beside_it_faces_its_scanner(angle):
    """The dragon scans' frames have their origin just below the dragon: from there a
    scan taken from +z still passes the depth-map test, and turning its normals towards
    the origin put 84% of them inside out (scan 72). Its view's axis is far from the
    origin's direction, so the scan is oriented as a view (towards +z, its scanner)."""
    from o3d_spectral.harness.real import DRAGON_SENSOR, real_dir

    scan = o3d.io.read_point_cloud(str(real_dir() / "dragon" / f"dragonStandRight_{angle}.ply"))
    prepared = prepare(as_arrays(scan), 0.005)
    rays = np.asarray(DRAGON_SENSOR) - prepared.normal_points
    assert np.mean(np.einsum("ij,ij->i", prepared.normals, rays) > 0.0) >= 0.99
    assert prepared.reading.orientation == "hemisphere"
    assert prepared.reading.view is not None


def test_each_cloud_can_name_its_own_sensor():
    """Two scans from two places: the source's sensor (source frame) orients the
    source's estimated normals, the target's the target's."""
    case = load_cases(["dragon_24"])[0]
    cloud = o3d_spectral.CloudOption(camera_location=(0.0, 0.0, 10.0),
                                     source_camera_location=(0.0, 0.0, -10.0))
    stepper = o3d_spectral.SpectralStepper(case.target, 0.005, cloud=cloud)
    moving = stepper.moving(case.source)
    assert stepper.target_reading.orientation == moving.reading.orientation == "camera"
    assert stepper.target_reading.view[2] > 0.9 and moving.reading.view[2] < -0.9
    with pytest.raises(ValueError, match="source_camera_location"):
        o3d_spectral.CloudOption(source_camera_location=(0.0, np.nan, 1.0))


def test_a_perfect_sphere_with_random_signs_is_oriented_outward():
    """Exactly cospherical points, which Qhull cannot triangulate for the propagation."""
    points = _sphere(3000, 0.1)
    signs = np.random.default_rng(1).choice([-1.0, 1.0], size=(3000, 1))
    cloud = np.c_[points, points / 0.1 * signs]
    result = o3d_spectral.registration_spectral(cloud, cloud, VOXEL)
    assert result.source_reading.normals_from == "re-oriented"
    assert np.all(np.isfinite(result.transformation))
    oriented, _ = orient(points, points / 0.1 * signs, VOXEL)
    assert np.mean(np.einsum("ij,ij->i", oriented, points) > 0) > 0.99
