"""The target's voxel grid: what decides its extent (issue 17)."""

from __future__ import annotations

import numpy as np
import pytest

from o3d_spectral import SpectralStepper
from tests.conftest import sample_model

VOXEL = 0.008


@pytest.mark.xfail(strict=True, reason="issue 17: grid extents from robust bounds")
def test_far_outliers_do_not_change_the_grid():
    """20 stray points 2 m from a cloud (flying pixels, a far wall) leave the target
    grid's shape as it is: its extent comes from robust bounds, not the raw min and max,
    or a few points make every FFT of the registration hundreds of times larger."""
    cloud = sample_model("mustard_bottle", n=5000)
    points = np.asarray(cloud.points)
    rng = np.random.default_rng(0)
    far = points.mean(axis=0) + [2.0, 0.0, 0.0] + rng.normal(scale=0.01, size=(20, 3))
    clean = SpectralStepper(points, VOXEL).grid
    noisy = SpectralStepper(np.vstack([points, far]), VOXEL).grid
    assert noisy.box.shape == clean.box.shape
