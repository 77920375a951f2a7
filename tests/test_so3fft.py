import itertools

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from o3d_spectral import egi, rotation, so3, so3fft, wigner


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
