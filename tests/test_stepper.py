"""The stepper drives a captured cloud onto the reference, as a servoing loop does."""

import numpy as np
import open3d as o3d
import pytest

import o3d_spectral
from o3d_spectral import so3
from o3d_spectral.harness.errors import rotation_error, translation_error
from tests.conftest import sample_model
from tests.test_registration import random_motion


def test_repeated_steps_bring_the_cloud_onto_the_reference():
    reference = sample_model("power_drill", 8000)
    stepper = o3d_spectral.SpectralStepper(reference, 0.008)
    start = random_motion(np.random.default_rng(4), max_angle_deg=25, max_translation=0.04)
    current = o3d.geometry.PointCloud(reference).transform(start)
    moved = np.eye(4)  # what the steps did to the cloud so far
    for _ in range(40):
        step = stepper.step(current)
        current.transform(step.transformation)
        moved = step.transformation @ moved
        if np.linalg.norm(step.evaluation.translation) < 2e-4 and np.linalg.norm(
            step.evaluation.rotation
        ) < 1e-3:
            break
    total = moved @ start  # should be the identity
    assert rotation_error(total, np.eye(4)) < 0.5
    center = np.asarray(reference.points).mean(axis=0)
    assert translation_error(total, np.eye(4), center=center) < 0.002
    assert stepper.level == stepper.levels - 1


def test_step_increments_follow_the_gains():
    reference = sample_model("cracker_box", 5000)
    option = o3d_spectral.SpectralRegistrationOption(lambda_t=0.3, lambda_r=0.2)
    stepper = o3d_spectral.SpectralStepper(reference, 0.008, option=option)
    shifted = np.asarray(reference.points) + [0.02, -0.01, 0.0]
    step = stepper.step(np.hstack([shifted, np.asarray(reference.normals)]))
    np.testing.assert_allclose(step.evaluation.translation, [-0.02, 0.01, 0.0], atol=5e-4)
    np.testing.assert_allclose(step.delta_translation, 0.3 * step.evaluation.translation)
    assert np.linalg.norm(step.evaluation.rotation) < 1e-2  # no rotation to correct
    M = step.transformation
    np.testing.assert_allclose(M[:3, :3], step.delta_rotation)
    pivot = np.r_[step.pivot, 1.0]
    np.testing.assert_allclose(M @ pivot, pivot + np.r_[step.delta_translation, 0.0])
    stepper.reset()
    assert stepper.level == 0


def test_stepper_rejects_bad_voxel_size():
    with pytest.raises(ValueError, match="voxel_size"):
        o3d_spectral.SpectralStepper(np.zeros((100, 3)), 0.0)


def _object_on_a_wide_plane(shift):
    """A drill (2000 points) moved by ``shift`` metres, on a 1.2 m x 1.2 m plane of points
    (a small object in a large scene), as arrays (N, 6) with normals."""
    drill = sample_model("power_drill", 2000)
    obj = np.hstack([np.asarray(drill.points) + shift, np.asarray(drill.normals)])
    u = np.linspace(-0.6, 0.6, 121)
    x, y = np.meshgrid(u, u)
    plane = np.column_stack([x.ravel(), y.ravel(), np.full(x.size, -0.15)])
    normals = np.tile([0.0, 0.0, 1.0], (len(plane), 1))
    return drill, np.vstack([obj, np.hstack([plane, normals])])


def test_windowed_search_finds_the_global_shift_on_a_smaller_grid():
    shift = np.array([0.23, -0.17, 0.05])
    drill, scene = _object_on_a_wide_plane(shift)
    stepper = o3d_spectral.SpectralStepper(scene, 0.008)
    moving = stepper.moving(drill)
    whole = stepper.evaluate(moving)
    np.testing.assert_allclose(whole.translation, shift, atol=0.15 * 0.008)  # sub-voxel
    expected = moving.centroid + shift
    window = stepper.search_box(moving, around=expected + 0.01)
    assert np.prod(window.shape) < np.prod(stepper.target_box.shape) / 4
    windowed = stepper.evaluate(moving, around=expected + 0.01)
    np.testing.assert_allclose(windowed.translation, whole.translation, atol=0.05 * 0.008)
    # Without a prediction, or with the window off, the whole grid is searched.
    assert stepper.search_box(moving) is stepper.target_box
    off = o3d_spectral.SpectralStepper(
        scene, 0.008, option=o3d_spectral.SpectralRegistrationOption(translation_window=None)
    )
    assert off.search_box(off.moving(drill), around=expected) is off.target_box


def test_coarsened_stepper_places_rotations_on_a_coarser_grid():
    """A rotated drill on a wide plane: the coarse stepper (voxels twice as large, half
    as many per axis, give or take the margins) places it within a coarse voxel, and
    the candidate rotation nearest the truth gets the highest peak; the stepper it came
    from is unchanged."""
    shift = np.array([0.23, -0.17, 0.05])
    drill, scene = _object_on_a_wide_plane(shift)
    stepper = o3d_spectral.SpectralStepper(scene, 0.008)
    grid, box = stepper._target_grid.copy(), stepper.target_box
    coarse = stepper.coarsened(2)
    assert coarse.voxel_size == 0.016
    assert all(c <= f // 2 + 3 for c, f in zip(coarse.target_box.shape, box.shape, strict=True))
    assert stepper.voxel_size == 0.008 and stepper.target_box is box
    np.testing.assert_array_equal(stepper._target_grid, grid)
    turn = so3.exp([0.0, 0.0, 0.5])  # the drill in the scene turned by 0.5 rad about z
    centre = drill.get_center()
    turned = (np.asarray(drill.points) - centre) @ turn.T + centre
    moving = coarse.moving(np.hstack([turned, np.asarray(drill.normals) @ turn.T]))
    undo = turn.T
    candidates = [so3.exp([0.0, 0.0, a]) @ undo for a in (0.0, 0.6, 1.5, 3.0)]
    found = coarse.hypotheses(moving, rotations=candidates)
    assert len(found) == len(candidates)
    best = max(found, key=lambda h: h.translation_peak)
    np.testing.assert_allclose(best.rotation, undo)
    np.testing.assert_allclose(best.centre, centre + shift, atol=0.016)


def test_window_is_not_used_where_it_would_not_shrink_the_fft():
    drill = sample_model("power_drill", 2000)
    stepper = o3d_spectral.SpectralStepper(drill, 0.008)
    moving = stepper.moving(drill)
    assert stepper.search_box(moving, around=moving.centroid) is stepper.target_box


def test_focused_egi_is_that_of_the_normals_in_the_ball():
    drill = sample_model("power_drill", 2000)
    shift = np.array([0.3, 0.2, 0.0])
    obj = np.hstack([np.asarray(drill.points) + shift, np.asarray(drill.normals)])
    u = np.linspace(-0.6, 0.6, 61)
    x, y = np.meshgrid(u, u)
    plane = np.column_stack([x.ravel(), y.ravel(), np.full(x.size, -0.6)])
    scene = np.vstack([obj, np.hstack([plane, np.tile([0.0, 0.0, 1.0], (len(plane), 1))])])
    stepper = o3d_spectral.SpectralStepper(scene, 0.008)
    alone = o3d_spectral.SpectralStepper(obj, 0.008)
    centre = obj[:, :3].mean(axis=0)
    radius = np.linalg.norm(obj[:, :3] - centre, axis=1).max() + 0.01
    focused = stepper.focused(centre[None, :], radius)
    assert focused is not stepper
    for level in range(stepper.levels):
        np.testing.assert_allclose(
            focused.target_coefficients[level], alone.target_coefficients[level], atol=1e-12
        )
        assert not np.allclose(stepper.target_coefficients[level], alone.target_coefficients[level])
    assert focused.target_box is stepper.target_box  # the translation search is shared
    # A fixed cloud that is all in the ball has nothing to focus on.
    assert alone.focused(centre[None, :], radius) is alone
    # Near the object's own points: the same normals.
    near = stepper.focused(obj[:, :3], 0.001)
    np.testing.assert_allclose(near.target_coefficients[-1], alone.target_coefficients[-1])


def test_global_steps_head_for_a_far_rotation_then_hand_over_to_the_law():
    """From 120 degrees, beyond the law's reach, the global search's correction is the
    true one (to the grid's resolution), its increments follow the gains, and the law
    takes over once the best hypothesis is within the handover angle."""
    reference = sample_model("power_drill", 8000)
    option = o3d_spectral.SpectralRegistrationOption(rotation_search="global")
    stepper = o3d_spectral.SpectralStepper(reference, 0.008, option=option)
    assert stepper.searching
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    start = np.eye(4)
    start[:3, :3] = so3.exp(np.deg2rad(120.0) * axis)
    start[:3, 3] = [0.05, -0.02, 0.03]
    current = o3d.geometry.PointCloud(reference).transform(start)
    step = stepper.step(current)
    assert stepper.searching  # still far: this was a global step
    full = np.eye(4)
    full[:3, :3] = so3.exp(step.evaluation.rotation)
    pivot = step.pivot
    full[:3, 3] = pivot + step.evaluation.translation - full[:3, :3] @ pivot
    assert rotation_error(full @ start, np.eye(4)) < 6.0  # Euler grid step: 5.6 degrees
    w = step.evaluation.rotation  # the gain, capped at max_rotation_step
    applied = min(0.5 * np.linalg.norm(w), option.max_rotation_step) / np.linalg.norm(w)
    np.testing.assert_allclose(step.delta_rotation, so3.exp(applied * w), atol=1e-12)
    moved = step.transformation @ start
    for _ in range(12):
        current = o3d.geometry.PointCloud(reference).transform(moved)
        step = stepper.step(current)
        moved = step.transformation @ moved
        if not stepper.searching:
            break
    assert not stepper.searching
    assert rotation_error(moved, np.eye(4)) < 15.0
    stepper.reset()
    assert stepper.searching and stepper.level == 0


@pytest.mark.parametrize("law_reach, searching_after", [(np.deg2rad(15.0), False), (1e-6, True)])
def test_law_turning_beyond_its_reach_restarts_the_global_search(law_reach, searching_after):
    """A 5-degree start is handed to the law at once (handover angle 30 degrees); the law's
    first turn stays within a 15-degree reach, but exceeds a reach of 1e-6 rad, which
    sends the stepper back to the global search at the coarse level."""
    reference = sample_model("mustard_bottle", 6000)
    option = o3d_spectral.SpectralRegistrationOption(
        rotation_search="global", handover_angle=np.deg2rad(30.0), law_reach=law_reach
    )
    stepper = o3d_spectral.SpectralStepper(reference, 0.008, option=option)
    start = np.eye(4)
    start[:3, :3] = so3.exp(np.deg2rad(5.0) * np.array([0.0, 0.6, 0.8]))
    step = stepper.step(o3d.geometry.PointCloud(reference).transform(start))
    assert so3.rotation_angle(step.delta_rotation) > 1e-6  # the law turned
    assert stepper.searching is searching_after


def test_visible_correlation_ranks_the_rotation_of_a_view_first():
    """Instance 21 of the partial suite (seed 0), a power drill seen from one side: the
    whole model's EGI correlation puts the right rotation 7th among its peaks; weighted
    and normalised as the sensor sees it (``search_visibility``), it is the first."""
    from o3d_spectral.harness.errors import symmetric_rotation_error
    from o3d_spectral.so3fft import peaks
    from o3d_spectral.synthetic.scenes import make_instance
    from o3d_spectral.synthetic.suite import instance_rng

    instance = make_instance("partial", "power_drill", rng=instance_rng(0, 21))
    ranks = {}
    for visibility in (True, False):
        option = o3d_spectral.SpectralRegistrationOption(search_visibility=visibility)
        stepper = o3d_spectral.SpectralStepper(instance.target, 0.008, option=option)
        assert stepper.viewpoint is not None
        moving = stepper.moving(instance.source)
        errors = []
        for R, _ in peaks(stepper.rotation_grid(moving), count=8):
            estimate = np.eye(4)
            estimate[:3, :3] = R
            errors.append(symmetric_rotation_error(estimate, instance.T_gt, instance.symmetry))
        right = np.flatnonzero(np.asarray(errors) < 15.0)
        ranks[visibility] = int(right[0]) if len(right) else None
    assert ranks == {True: 0, False: 6}
