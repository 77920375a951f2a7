"""The servo law drives a captured cloud onto the reference, as a servoing loop does:
the paper's law alone, or the global search first and the law after the handover."""

import numpy as np
import open3d as o3d
import pytest

from o3d_spectral import GlobalSearchOption, SpectralRegistrationOption
from o3d_spectral.harness.errors import rotation_error, translation_error
from o3d_spectral.servo import ServoLaw
from o3d_spectral.spectra import so3
from tests.conftest import sample_model
from tests.test_registration import random_motion


def test_repeated_steps_bring_the_cloud_onto_the_reference():
    reference = sample_model("power_drill", 8000)
    law = ServoLaw(reference, 0.008)
    start = random_motion(np.random.default_rng(4), max_angle_deg=25, max_translation=0.04)
    current = o3d.geometry.PointCloud(reference).transform(start)
    moved = np.eye(4)  # what the steps did to the cloud so far
    for _ in range(40):
        step = law.step(current)
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
    assert law.finest


def test_step_increments_follow_the_gains():
    reference = sample_model("cracker_box", 5000)
    option = SpectralRegistrationOption(lambda_t=0.3, lambda_r=0.2)
    law = ServoLaw(reference, 0.008, option=option)
    shifted = np.asarray(reference.points) + [0.02, -0.01, 0.0]
    step = law.step(np.hstack([shifted, np.asarray(reference.normals)]))
    np.testing.assert_allclose(step.evaluation.translation, [-0.02, 0.01, 0.0], atol=5e-4)
    np.testing.assert_allclose(step.delta_translation, 0.3 * step.evaluation.translation)
    assert np.linalg.norm(step.evaluation.rotation) < 1e-2  # no rotation to correct
    M = step.transformation
    np.testing.assert_allclose(M[:3, :3], step.delta_rotation)
    pivot = np.r_[step.pivot, 1.0]
    np.testing.assert_allclose(M @ pivot, pivot + np.r_[step.delta_translation, 0.0])
    law.reset()
    assert law.level == 0


def test_later_law_cycles_search_the_shift_about_what_the_last_one_left():
    """After a first cycle over the whole grid, each capture's shift is searched about the
    translation the previous cycle left to do, and reads what the whole grid reads."""
    reference = sample_model("cracker_box", 5000)
    law = ServoLaw(reference, 0.008)
    seen = []
    evaluate = law.stepper.evaluate
    law.stepper.evaluate = lambda *a, **k: seen.append(k.get("around")) or evaluate(*a, **k)
    current = o3d.geometry.PointCloud(reference).translate([0.03, -0.02, 0.01])
    first = law.step(current)
    current.transform(first.transformation)
    second = law.step(current)
    assert seen[0] is None
    left = first.evaluation.translation - first.delta_translation
    moving = law.stepper.moving(current)
    np.testing.assert_allclose(seen[1], moving.centroid + left)
    whole = evaluate(moving, level=law.level)  # no prediction: the whole grid
    np.testing.assert_allclose(second.evaluation.translation, whole.translation, atol=4e-4)


@pytest.mark.slow
def test_global_steps_head_for_a_far_rotation_then_hand_over_to_the_law():
    """From 120 degrees, beyond the law's reach, the global search's correction is the
    true one (to the grid's resolution), its increments follow the gains, and the law
    takes over once the best hypothesis is within the handover angle."""
    reference = sample_model("power_drill", 8000)
    law = ServoLaw(reference, 0.008, search=GlobalSearchOption())
    assert law.searching
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    start = np.eye(4)
    start[:3, :3] = so3.exp(np.deg2rad(120.0) * axis)
    start[:3, 3] = [0.05, -0.02, 0.03]
    current = o3d.geometry.PointCloud(reference).transform(start)
    step = law.step(current)
    assert law.searching  # still far: this was a global step
    full = np.eye(4)
    full[:3, :3] = so3.exp(step.evaluation.rotation)
    pivot = step.pivot
    full[:3, 3] = pivot + step.evaluation.translation - full[:3, :3] @ pivot
    assert rotation_error(full @ start, np.eye(4)) < 6.0  # Euler grid step: 5.6 degrees
    w = step.evaluation.rotation  # the gain, capped at max_rotation_step
    applied = min(0.5 * np.linalg.norm(w), law.stepper.option.max_rotation_step) / np.linalg.norm(w)
    np.testing.assert_allclose(step.delta_rotation, so3.exp(applied * w), atol=1e-12)
    moved = step.transformation @ start
    for _ in range(12):
        current = o3d.geometry.PointCloud(reference).transform(moved)
        step = law.step(current)
        moved = step.transformation @ moved
        if not law.searching:
            break
    assert not law.searching
    assert rotation_error(moved, np.eye(4)) < 15.0
    law.reset()
    assert law.searching and law.level == 0


@pytest.mark.parametrize("law_reach, searching_after", [(np.deg2rad(15.0), False), (1e-6, True)])
def test_law_turning_beyond_its_reach_restarts_the_global_search(law_reach, searching_after):
    """A 5-degree start is handed to the law at once (handover angle 30 degrees); the law's
    first turn stays within a 15-degree reach, but exceeds a reach of 1e-6 rad, which
    sends the law back to the global search at the coarse level."""
    reference = sample_model("mustard_bottle", 6000)
    law = ServoLaw(
        reference, 0.008, search=GlobalSearchOption(), handover_angle=np.deg2rad(30.0),
        law_reach=law_reach,
    )
    start = np.eye(4)
    start[:3, :3] = so3.exp(np.deg2rad(5.0) * np.array([0.0, 0.6, 0.8]))
    step = law.step(o3d.geometry.PointCloud(reference).transform(start))
    assert so3.rotation_angle(step.delta_rotation) > 1e-6  # the law turned
    assert law.searching is searching_after


