"""The stepper drives a captured cloud onto the reference, as a servoing loop does."""

import numpy as np
import open3d as o3d
import pytest

import o3d_spectral
from o3d_spectral.symmetry import rotation_error, translation_error
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
