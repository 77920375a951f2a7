import numpy as np
import pytest
from scipy.special import sph_harm_y

from o3d_spectral.spectra import harmonics
from tests.conftest import band_limited


@pytest.mark.parametrize("bandwidth", [1, 2, 4, 16, 32, 64])
def test_sht_round_trip_of_band_limited_function(bandwidth, rng):
    F = band_limited(bandwidth, rng)
    samples = harmonics.isht(F)
    assert samples.shape == (2 * bandwidth, 2 * bandwidth)
    np.testing.assert_allclose(harmonics.sht(samples, bandwidth), F, atol=1e-10, rtol=0)


@pytest.mark.parametrize("bandwidth", [2, 8, 16])
def test_quadrature_weights_integrate_sphere(bandwidth):
    w = harmonics.quadrature_weights(bandwidth)
    assert w.sum() * 2 * bandwidth == pytest.approx(4 * np.pi, rel=1e-13)
    # Exact for polynomials of degree < 2B in cos(theta): integral of cos^2 = 4 pi / 3.
    theta, _ = harmonics.grid_angles(bandwidth)
    if bandwidth > 1:
        assert np.sum(w * np.cos(theta) ** 2) * 2 * bandwidth == pytest.approx(4 * np.pi / 3)


def test_real_harmonics_match_scipy(rng):
    B = 8
    theta, phi = rng.uniform(0, np.pi, 30), rng.uniform(-np.pi, np.pi, 30)
    S = harmonics.real_sph_harm(B, theta, phi)
    for l in range(B):  # noqa: E741
        for m in range(-l, l + 1):
            Y = sph_harm_y(l, abs(m), theta, phi)  # Condon-Shortley phase included
            if m > 0:
                expected = np.sqrt(2) * (-1) ** m * Y.real
            elif m < 0:
                expected = np.sqrt(2) * (-1) ** m * Y.imag
            else:
                expected = Y.real
            np.testing.assert_allclose(S[:, l, m + B - 1], expected, atol=1e-12)


def test_degree_one_is_proportional_to_y_z_x(rng):
    x = rng.normal(size=(10, 3))
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    S = harmonics.real_sph_harm(2, np.arccos(x[:, 2]), np.arctan2(x[:, 1], x[:, 0]))
    np.testing.assert_allclose(S[:, 1, :], np.sqrt(3 / (4 * np.pi)) * x[:, [1, 2, 0]], atol=1e-14)


def test_harmonics_are_orthonormal_on_the_grid():
    B = 8
    theta, phi = harmonics.grid_angles(B)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    S = harmonics.real_sph_harm(B, t.ravel(), p.ravel()).reshape(2 * B, 2 * B, -1)
    w = harmonics.quadrature_weights(B)[:, None, None]
    gram = np.einsum("jka,jkb->ab", S * w, S)
    mask = (np.abs(np.arange(-(B - 1), B))[None, :] <= np.arange(B)[:, None]).ravel()
    np.testing.assert_allclose(gram[np.ix_(mask, mask)], np.eye(mask.sum()), atol=1e-12)


@pytest.mark.parametrize("count", [2, 64, 300])  # under, at and across the kernel's block
def test_project_equals_sum_of_harmonics(rng, count):
    B = 12
    n = rng.normal(size=(count, 3))
    n[0] = [0, 0, 1]  # the poles, where the longitude is undefined
    n[1] = [0, 0, -3]
    w = rng.uniform(0.5, 2.0, len(n))
    u = n / np.linalg.norm(n, axis=1, keepdims=True)
    S = harmonics.real_sph_harm(B, np.arccos(u[:, 2]), np.arctan2(u[:, 1], u[:, 0]))
    np.testing.assert_allclose(harmonics.project(n, w, B), np.einsum("ilm,i->lm", S, w), atol=1e-11)


def test_bad_arguments():
    with pytest.raises(ValueError, match="bandwidth"):
        harmonics.grid_angles(0)
    with pytest.raises(ValueError, match="shape"):
        harmonics.sht(np.zeros((4, 5)), 2)
