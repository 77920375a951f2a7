import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from o3d_spectral.spectra import egi, harmonics, wigner


def test_histogram_counts_every_normal(rng):
    normals = rng.normal(size=(1000, 3))
    hist = egi.histogram(normals, 8)
    assert hist.shape == (16, 16) and hist.sum() == 1000


def test_histogram_bins_on_the_paper_grid():
    B = 4
    centres = egi.grid_points(B)
    hist = egi.histogram(centres.reshape(-1, 3), B)
    np.testing.assert_array_equal(hist, np.ones((2 * B, 2 * B)))


def test_binned_equals_projection_of_bin_centres(rng):
    """The paper's histogram is the exact EGI with every normal moved to its bin centre."""
    B = 8
    normals = rng.normal(size=(500, 3))
    hist = egi.histogram(normals, B)
    centres = egi.grid_points(B).reshape(-1, 3)
    expected = harmonics.project(centres, hist.ravel(), B)
    np.testing.assert_allclose(egi.coefficients(normals, B, binned=True), expected, atol=1e-10)


def test_direct_coefficients_rotate_exactly(rng):
    B = 12
    normals = rng.normal(size=(300, 3))
    R = Rotation.random(random_state=2).as_matrix()
    np.testing.assert_allclose(egi.coefficients(normals @ R.T, B),
                               wigner.rotate_coefficients(egi.coefficients(normals, B), R),
                               atol=1e-10)


def test_smoothing_is_a_heat_kernel(rng):
    F = rng.normal(size=(6, 11))
    S = egi.smooth(F, 0.2)
    l = np.arange(6)  # noqa: E741
    np.testing.assert_allclose(S / F, np.exp(-0.5 * l * (l + 1) * 0.04)[:, None] * np.ones((1, 11)))
    np.testing.assert_array_equal(egi.smooth(F, 0.0), F)


def test_normalise(rng):
    F = egi.normalise(egi.coefficients(rng.normal(size=(50, 3)), 6))
    assert np.linalg.norm(F) == pytest.approx(1.0)
    assert np.all(F[0] == 0)
    with pytest.raises(ValueError, match="no rotation information"):
        egi.normalise(np.eye(6, 11) * [[1]] * (np.arange(6)[:, None] == 0))


def test_harmonics_table_gives_the_coefficients_of_any_weighted_subset():
    rng = np.random.default_rng(3)
    normals = rng.normal(size=(200, 3))
    table = egi.harmonics_table(normals, 12)
    assert table.shape == (200, 12 * 23)
    subset = rng.random(200) < 0.4
    weights = rng.random(subset.sum())
    np.testing.assert_allclose(
        (weights @ table[subset]).reshape(12, 23),
        egi.coefficients(normals[subset], 12, weights=weights),
        atol=1e-12,
    )


@pytest.mark.parametrize("binned", [False, True])
def test_two_sided_egi_has_only_even_degrees_and_ignores_signs(rng, binned):
    """Each normal counted both ways at half weight: the odd degrees vanish, the even ones
    are the one-sided EGI's, and flipping any normal changes nothing."""
    B = 10
    normals = rng.normal(size=(400, 3))
    weights = rng.random(400)
    one = egi.coefficients(normals, B, weights=weights, binned=binned)
    two = egi.coefficients(normals, B, weights=weights, binned=binned, two_sided=True)
    assert np.abs(one[1::2]).max() > 1e-3  # a one-sided EGI has odd degrees
    np.testing.assert_array_equal(two[1::2], 0.0)
    np.testing.assert_array_equal(two[0::2], one[0::2])
    flips = rng.choice([-1.0, 1.0], size=(400, 1))
    flipped = egi.coefficients(normals * flips, B, weights=weights, binned=binned, two_sided=True)
    np.testing.assert_allclose(flipped, two, atol=1e-10)
    if not binned:  # the definition: n and -n, half the weight each
        both = np.vstack([normals, -normals])
        halves = np.r_[weights, weights] / 2
        np.testing.assert_allclose(egi.coefficients(both, B, weights=halves), two, atol=1e-10)
