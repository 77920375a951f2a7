"""Turns of a doubtful pose about the axis its inliers hold least
(o3d_spectral.search.turns, the ``turns`` stage of the global call), and the surfaces that
leave a motion free (o3d_spectral.evidence.free_motions.leaves_motion_free)."""

import numpy as np
import pytest

import o3d_spectral
from o3d_spectral.evidence.free_motions import leaves_motion_free
from o3d_spectral.evidence.pose import least_supported_motion
from o3d_spectral.harness.metrics import instance_score
from o3d_spectral.search.turns import MAX_SUPPORT, holds_every_motion, turn_axis, turned
from o3d_spectral.spectra import so3
from o3d_spectral.synthetic.sampling import rigid
from o3d_spectral.synthetic.turntable import turntable_pair
from tests.test_confidence import mug_like

VOXEL = 0.008


def moved_mug(rng, motion):
    """:func:`mug_like` (axis z through the origin) moved by ``motion`` (4, 4)."""
    points, normals, tab = mug_like(rng)
    return points @ motion[:3, :3].T + motion[:3, 3], normals @ motion[:3, :3].T, tab


def test_the_least_supported_motion_of_a_mug_missing_its_handle_is_the_turn_about_its_body():
    """The body matched and the tab missed: the motion the inliers resist least is the
    turn about the body's axis, wherever the mug stands; the axis found is that line (its
    direction, and a point on it)."""
    motion = rigid(so3.exp(np.array([0.4, -0.9, 0.3])), np.array([0.3, -0.2, 1.5]))
    points, normals, tab = moved_mug(np.random.default_rng(0), motion)
    least = least_supported_motion(points, normals, ~tab)
    assert least.share < MAX_SUPPORT and not holds_every_motion(least.share)
    axis = turn_axis(least)
    assert axis is not None
    true_direction, true_point = motion[:3, 2], motion[:3, 3]
    assert abs(axis.direction @ true_direction) == pytest.approx(1.0, abs=1e-3)
    offset = axis.point - true_point  # on the line: no part across it
    assert np.linalg.norm(offset - (offset @ true_direction) * true_direction) < 1e-3


def test_a_held_pose_or_a_slide_gives_no_axis():
    """Every point an inlier: every motion held, no turn to try. A can's side matched and
    its lid missed: only the lid resists the slide along the axis, which is the weakest
    motion, and a slide is no turn."""
    points, normals, _ = mug_like(np.random.default_rng(1))
    assert turn_axis(least_supported_motion(points, normals, np.ones(len(points), bool))) is None
    rng = np.random.default_rng(2)
    side = rng.uniform([0.0, -0.05], [2.0 * np.pi, 0.05], size=(2000, 2))
    radial = np.c_[np.cos(side[:, 0]), np.sin(side[:, 0]), np.zeros(len(side))]
    ring = np.sqrt(rng.uniform(0.0, 0.04**2, 300)) * np.exp(1j * rng.uniform(0, 2 * np.pi, 300))
    can = np.r_[np.c_[0.04 * radial[:, :2], side[:, 1]], np.c_[ring.real, ring.imag,
                                                               np.full(300, 0.05)]]
    can_normals = np.r_[radial, np.tile([0.0, 0.0, 1.0], (300, 1))]
    least = least_supported_motion(can, can_normals, np.r_[np.ones(2000, bool),
                                                           np.zeros(300, bool)])
    assert least.share < MAX_SUPPORT and abs(least.translation[2]) > 0.9
    assert turn_axis(least) is None
    assert turn_axis(None) is None


def test_turned_poses_turn_about_the_axis_in_even_steps():
    """``count - 1`` poses, the k-th the pose followed by a turn of k * 360 / count
    degrees about the axis: points on the axis stay where the pose put them."""
    points, normals, tab = mug_like(np.random.default_rng(3))
    axis = turn_axis(least_supported_motion(points, normals, ~tab))
    pose = rigid(so3.exp(np.array([0.1, 0.2, -0.3])), np.array([0.01, 0.02, 0.03]))
    poses = turned(pose, axis, 12)
    assert len(poses) == 11
    on_axis = np.linalg.solve(pose[:3, :3], axis.point + 0.05 * axis.direction - pose[:3, 3])
    for k, turned_pose in enumerate(poses, start=1):
        relative = turned_pose @ np.linalg.inv(pose)
        assert so3.rotation_angle(relative[:3, :3]) == pytest.approx(
            min(30.0 * k, 360.0 - 30.0 * k) * np.pi / 180.0, abs=1e-6)
        assert np.allclose(turned_pose[:3, :3] @ on_axis + turned_pose[:3, 3],
                           pose[:3, :3] @ on_axis + pose[:3, 3], atol=1e-12)


def test_a_body_of_revolution_alone_leaves_its_turn_free_and_a_handle_holds_it():
    """A cup (side and bottom) without its tab leaves the turn about its axis free; with
    the tab (6% of the points) every motion is held; so is a box's corner."""
    points, normals, tab = mug_like(np.random.default_rng(4))
    rng = np.random.default_rng(5)
    disc = np.sqrt(rng.uniform(0.0, 0.04**2, 300)) * np.exp(1j * rng.uniform(0, 2 * np.pi, 300))
    bottom = np.c_[disc.real, disc.imag, np.full(300, -0.05)]
    down = np.tile([0.0, 0.0, -1.0], (300, 1))
    assert leaves_motion_free(np.r_[points[~tab], bottom], np.r_[normals[~tab], down])
    assert not leaves_motion_free(np.r_[points, bottom], np.r_[normals, down])
    faces = [np.c_[rng.uniform(0, 0.1, (500, 2)), np.zeros(500)][:, order]
             for order in ([0, 1, 2], [0, 2, 1], [2, 0, 1])]
    corner_normals = np.repeat(np.eye(3)[[2, 1, 0]], 500, axis=0)
    assert not leaves_motion_free(np.concatenate(faces), corner_normals)


def test_two_views_of_the_mug_showing_its_handle_are_turned_to_the_right_pose():
    """Two views of the mug 45 degrees apart on a turntable, both showing its handle:
    every candidate leads to the pose that overlaps the whole visible body (the view
    turned as if the camera had not moved), warned; turned about the axis its inliers
    hold least, the handle lands on the handle, and the pose is right and confident."""
    pair = turntable_pair("mug", 45, 30, np.random.default_rng(2))
    score = instance_score(pair)
    searched = o3d_spectral.registration_spectral_global(
        pair.source, pair.target, VOXEL, search=o3d_spectral.GlobalSearchOption(turns=0))
    turned_result = o3d_spectral.registration_spectral_global(pair.source, pair.target, VOXEL)
    assert not score(np.asarray(searched.transformation))[2] and searched.confidence < 0.5
    assert "turns" not in searched.stage_times
    assert score(np.asarray(turned_result.transformation))[2], score(
        np.asarray(turned_result.transformation))
    assert turned_result.confidence > 0.5 and "turns" in turned_result.stage_times


def test_turns_must_be_a_count():
    with pytest.raises(ValueError, match="turns"):
        o3d_spectral.GlobalSearchOption(turns=-1)
