import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from o3d_spectral.spectra import egi, rotation, so3, wigner


@pytest.fixture
def spectra(rng):
    normals = rng.normal(size=(400, 3)) * [1.0, 2.0, 3.0]
    F = egi.normalise(egi.coefficients(normals, 12, sigma=0.1))
    R_true = Rotation.random(random_state=5).as_matrix()
    return F, wigner.rotate_coefficients(F, R_true), R_true


def test_gradient_matches_finite_differences(spectra):
    F, G, _ = spectra
    R = Rotation.random(random_state=9).as_matrix()
    local = rotation.gradient(F, G, R)
    eps = 1e-6
    for k in range(3):
        e = np.zeros(3)
        e[k] = eps
        fd = (rotation.correlation(F, G, R @ so3.exp(e))
              - rotation.correlation(F, G, R @ so3.exp(-e))) / (2 * eps)
        assert local.gradient[k] == pytest.approx(fd, rel=1e-6, abs=1e-10)
    assert local.value == pytest.approx(rotation.correlation(F, G, R))


def test_hessian_matches_finite_differences(spectra):
    F, G, _ = spectra
    R = Rotation.random(random_state=11).as_matrix()
    H = rotation.gradient(F, G, R).hessian
    h = 1e-4
    E = np.eye(3) * h
    for j in range(3):
        for k in range(3):
            c = [rotation.correlation(F, G, R @ so3.exp(sj * E[j] + sk * E[k]))
                 for sj, sk in ((1, 1), (1, -1), (-1, 1), (-1, -1))]
            assert H[j, k] == pytest.approx((c[0] - c[1] - c[2] + c[3]) / (4 * h * h),
                                            rel=1e-4, abs=1e-8)


def test_peak_at_true_rotation(spectra):
    F, G, R_true = spectra
    local = rotation.gradient(F, G, R_true)
    np.testing.assert_allclose(local.gradient, 0.0, atol=1e-12)
    assert np.all(np.linalg.eigvalsh(local.hessian) < 0)
    # trace of the Hessian at the peak: the Casimir identity
    assert np.trace(local.hessian) / 3 == pytest.approx(-rotation.curvature_scale(F, G))
    assert local.value == pytest.approx(np.sum(F * F) / (4 * np.pi))
    assert rotation.rotation_cost(F, G, R_true) == pytest.approx(0.0, abs=1e-20)


@pytest.mark.parametrize("preconditioned", [True, False])
def test_step_climbs_to_the_true_rotation(spectra, preconditioned):
    F, G, R_true = spectra
    R = R_true @ so3.exp([0.2, -0.1, 0.15])
    scale = rotation.curvature_scale(F, G)
    for _ in range(100):
        R = R @ so3.exp(0.5 * rotation.rotation_step(rotation.gradient(F, G, R), scale,
                                                    preconditioned=preconditioned))
    assert np.rad2deg(so3.rotation_angle(R.T @ R_true)) < 1e-3


def test_newton_step_is_the_remaining_error_near_the_peak(spectra):
    F, G, R_true = spectra
    w = np.array([1e-3, -2e-3, 1.5e-3])
    step = rotation.rotation_step(rotation.gradient(F, G, R_true @ so3.exp(w)),
                                  rotation.curvature_scale(F, G))
    np.testing.assert_allclose(step, -w, atol=1e-5)
