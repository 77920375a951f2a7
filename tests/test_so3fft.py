import itertools

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from o3d_spectral.spectra import egi, harmonics, rotation, so3, so3fft, wigner


@pytest.fixture
def spectra(rng):
    F = egi.normalise(egi.coefficients(rng.normal(size=(300, 3)) * [1, 2, 3], 8, sigma=0.15))
    R_true = Rotation.random(random_state=4).as_matrix()
    return F, wigner.rotate_coefficients(F, R_true), R_true


@pytest.mark.parametrize("n_alpha, n_beta", [(16, 16), (15, 7), (40, 24)])
def test_grid_equals_direct_correlation(spectra, n_alpha, n_beta, rng):
    F, G, _ = spectra
    grid = so3fft.correlation_grid(F, G, n_alpha=n_alpha, n_beta=n_beta)
    assert grid.values.shape == (n_beta, n_alpha, n_alpha)
    for _ in range(20):
        index = (rng.integers(n_beta), rng.integers(n_alpha), rng.integers(n_alpha))
        assert grid.values[index] == pytest.approx(
            rotation.correlation(F, G, grid.rotation(index)), abs=1e-12
        )


def test_best_peak_is_within_a_grid_step_of_the_truth(spectra):
    F, G, R_true = spectra
    grid = so3fft.correlation_grid(F, G, n_alpha=48, n_beta=48)
    (best, value), *others = so3fft.peaks(grid, count=4)
    step = np.pi / 24  # the alpha/gamma step; beta's is half of it
    assert so3.rotation_angle(best.T @ R_true) < step
    assert all(value >= v for _, v in others)
    rotations = [best] + [R for R, _ in others]
    for a, b in itertools.combinations(rotations, 2):
        assert so3.rotation_angle(a.T @ b) >= np.deg2rad(15.0)


def test_too_coarse_grid_rejected(spectra):
    F, G, _ = spectra
    with pytest.raises(ValueError, match="n_alpha"):
        so3fft.correlation_grid(F, G, n_alpha=10)


def _cosine(A: np.ndarray, B: np.ndarray) -> float:
    """Cosine similarity of two expansions without their degree 0, over 4 pi."""
    A, B = A.copy(), B.copy()
    A[0], B[0] = 0.0, 0.0
    return float(np.sum(A * B) / (np.linalg.norm(A) * np.linalg.norm(B)) / (4 * np.pi))


@pytest.mark.parametrize("n_alpha, n_beta", [(16, 16), (24, 9)])
def test_visible_grid_equals_direct_cosine_of_the_weighted_turned_egi(n_alpha, n_beta, rng):
    """With a weight of degree 1, every product is band-limited: the identity is exact."""
    B = 8
    F = egi.coefficients(rng.normal(size=(400, 3)) * [1, 2, 3], B, sigma=0.2)
    F[B - 1 :] = 0.0  # degree < B - 1, so that w f_R stays below B
    G = egi.coefficients(rng.normal(size=(300, 3)) * [3, 1, 1], B, sigma=0.2)
    d = np.array([0.3, -0.5, 0.8])
    d /= np.linalg.norm(d)

    def weight(n):
        return 0.5 * (1.0 + n @ d)

    grid = so3fft.visible_correlation_grid(F, G, weight, n_alpha=n_alpha, n_beta=n_beta)
    fine = 2 * B
    points = egi.grid_points(fine)
    for _ in range(15):
        index = (rng.integers(n_beta), rng.integers(n_alpha), rng.integers(n_alpha))
        turned = harmonics.resize(wigner.rotate_coefficients(F, grid.rotation(index)), fine)
        seen = harmonics.resize(harmonics.sht(harmonics.isht(turned) * weight(points), fine), B)
        assert grid.values[index] == pytest.approx(_cosine(seen, G), abs=1e-10)


def test_visible_grid_with_unit_weight_is_the_plain_correlation(spectra):
    F, G, _ = spectra
    plain = so3fft.correlation_grid(F, G, n_alpha=16, n_beta=12)
    visible = so3fft.visible_correlation_grid(
        F, G, lambda n: np.ones(n.shape[:-1]), n_alpha=16, n_beta=12
    )
    np.testing.assert_allclose(visible.values, plain.values, atol=1e-12)


def test_visible_grid_finds_the_rotation_of_one_view(rng):
    """A target that is one view (normals facing the sensor, sampled by the cosine of
    incidence) of a turned model: the best peak lies within a grid step of the turn."""
    B = 16
    normals = rng.normal(size=(4000, 3)) * [1.0, 2.0, 4.0]
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    R_true = Rotation.random(random_state=7).as_matrix()
    d = np.array([0.0, 0.0, 1.0])
    turned = normals @ R_true.T
    cosine = turned @ d
    seen = cosine > 0
    F = egi.coefficients(normals, B, sigma=0.1)
    G = egi.coefficients(turned[seen], B, weights=cosine[seen], sigma=0.1)
    grid = so3fft.visible_correlation_grid(F, G, egi.facing(d), n_alpha=64, n_beta=64)
    (best, _), *_ = so3fft.peaks(grid, count=2)
    assert so3.rotation_angle(best.T @ R_true) < np.pi / 32


def test_facing_rejects_a_zero_direction():
    with pytest.raises(ValueError, match="direction"):
        egi.facing([0.0, 0.0, 0.0])


def test_stacked_grid_is_the_sum_of_each_pair_s_grid(rng):
    F, G = rng.normal(size=(3, 6, 11)), rng.normal(size=(3, 6, 11))
    stacked = so3fft.correlation_grid(F, G, n_alpha=14, n_beta=9).values
    each = sum(so3fft.correlation_grid(f, g, n_alpha=14, n_beta=9).values
               for f, g in zip(F, G, strict=True))
    np.testing.assert_allclose(stacked, each, atol=1e-12)
    with pytest.raises(ValueError, match="S, B, 2B - 1"):
        so3fft.correlation_grid(F, G[0])


def test_change_of_basis_equals_the_dense_products():
    """W d W^H by slices equals the dense complex products, for every bandwidth shape."""
    from o3d_spectral.spectra.so3fft import change_basis, diagonalising_basis

    rng = np.random.default_rng(0)
    for B in (1, 2, 5, 16):
        d = rng.standard_normal((3, B, 2 * B - 1, 2 * B - 1))
        W = diagonalising_basis(B)
        np.testing.assert_allclose(change_basis(d), W @ d @ W.conj().T, atol=1e-13)
