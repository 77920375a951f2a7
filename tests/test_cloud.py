"""Input clouds: isolated points do not size the grids."""

import numpy as np

import o3d_spectral
from o3d_spectral.io.cloud import dense_bounds
from tests.conftest import sample_model


def _with_normals(cloud):
    return np.hstack([np.asarray(cloud.points), np.asarray(cloud.normals)])


def test_outliers_far_away_leave_the_grids_unchanged():
    """20 stray points 2 m from a drill leave the fixed grid's shape and the moving
    cloud's centroid and radius as they are without them."""
    drill = _with_normals(sample_model("power_drill", 4000))
    rng = np.random.default_rng(1)
    stray = np.hstack([rng.normal(size=(20, 3)) * 0.01 + [2.0, 0.0, 0.0],
                       np.tile([0.0, 0.0, 1.0], (20, 1))])
    clean = o3d_spectral.SpectralStepper(drill, 0.008)
    noisy = o3d_spectral.SpectralStepper(np.vstack([drill, stray]), 0.008)
    assert noisy.grid.box.shape == clean.grid.box.shape
    a, b = clean.moving(drill), clean.moving(np.vstack([drill, stray]))
    np.testing.assert_allclose(b.centroid, a.centroid)
    assert b.radius == a.radius


def test_dense_bounds_keep_the_bulk_and_cut_only_isolated_ends():
    rng = np.random.default_rng(2)
    # Two blocks 0.3 m apart, each far over 1% of the points: nothing is isolated.
    blocks = np.vstack([rng.random((3000, 3)) * 0.1, rng.random((3000, 3)) * 0.1 + 0.4])
    lower, upper = dense_bounds(blocks, 0.008)
    np.testing.assert_array_equal(lower, blocks.min(axis=0))
    np.testing.assert_array_equal(upper, blocks.max(axis=0))
    # A few points beyond a wide gap, on both sides of one axis, are cut.
    stray = np.array([[-1.0, 0.05, 0.05], [-0.9, 0.05, 0.05], [3.0, 0.05, 0.05]])
    lower, upper = dense_bounds(np.vstack([blocks, stray]), 0.008)
    np.testing.assert_array_equal(lower, blocks.min(axis=0))
    np.testing.assert_array_equal(upper, blocks.max(axis=0))
    # Within the gap, nothing is cut.
    near = np.array([[-0.05, 0.05, 0.05]])
    lower, _ = dense_bounds(np.vstack([blocks, near]), 0.008)
    assert lower[0] == -0.05
