import numpy as np
import pytest
import scipy.linalg
from scipy.spatial.transform import Rotation

from o3d_spectral.spectra import egi, harmonics, so3, wigner
from tests.conftest import band_limited

B = 10


def _block(M, l):  # noqa: E741
    s = slice(M.shape[-1] // 2 - l, M.shape[-1] // 2 + l + 1)
    return M[..., s, s]


def _harmonics_at(x, bandwidth=B):
    return harmonics.real_sph_harm(
        bandwidth, np.arccos(np.clip(x[:, 2], -1, 1)), np.arctan2(x[:, 1], x[:, 0])
    )


@pytest.mark.parametrize("seed", range(5))
def test_representation_property(seed):
    R1 = Rotation.random(random_state=seed).as_matrix()
    R2 = Rotation.random(random_state=seed + 100).as_matrix()
    U12 = wigner.wigner_matrices(R1 @ R2, B)
    np.testing.assert_allclose(
        U12, wigner.wigner_matrices(R1, B) @ wigner.wigner_matrices(R2, B), atol=1e-12
    )


@pytest.mark.parametrize("seed", range(5))
def test_orthogonal_blocks(seed):
    U = wigner.wigner_matrices(Rotation.random(random_state=seed).as_matrix(), B)
    for l in range(B):  # noqa: E741
        Ul = _block(U[l], l)
        np.testing.assert_allclose(Ul @ Ul.T, np.eye(2 * l + 1), atol=1e-12)
        assert np.linalg.det(Ul) == pytest.approx(1.0)
    # nothing outside the blocks
    mask = np.zeros_like(U, dtype=bool)
    for l in range(B):  # noqa: E741
        mask[l, B - 1 - l : B + l, B - 1 - l : B + l] = True
    assert np.all(U[~mask] == 0.0)


def test_harmonics_transform_by_wigner_matrix(rng):
    """S(R x) = U(R) S(x): the defining identity."""
    R = Rotation.random(random_state=7).as_matrix()
    x = rng.normal(size=(40, 3))
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    expected = np.einsum("lmn,iln->ilm", wigner.wigner_matrices(R, B), _harmonics_at(x))
    np.testing.assert_allclose(_harmonics_at(x @ R.T), expected, atol=1e-12)


def test_degree_one_is_the_rotation_in_y_z_x_order():
    R = Rotation.random(random_state=3).as_matrix()
    P = np.array([[0, 1, 0], [0, 0, 1], [1, 0, 0]], dtype=float)
    np.testing.assert_allclose(_block(wigner.wigner_matrices(R, B)[1], 1), P @ R @ P.T, atol=1e-14)


@pytest.mark.parametrize("seed", range(3))
def test_rotating_a_band_limited_function_multiplies_its_coefficients(seed):
    """SHT of g(x) = f(R^T x) on the grid equals U(R) F.

    Paper, eq. real_fourier_transform_gr_simplified.
    """
    rng = np.random.default_rng(seed)
    F = band_limited(B, rng)
    R = Rotation.random(random_state=seed).as_matrix()
    grid = egi.grid_points(B).reshape(-1, 3)
    g = np.einsum("ilm,lm->i", _harmonics_at(grid @ R), F)  # f(R^T x): rows x^T R = (R^T x)^T
    G = harmonics.sht(g.reshape(2 * B, 2 * B), B)
    np.testing.assert_allclose(G, wigner.rotate_coefficients(F, R), atol=1e-10)


def test_generators_exponentiate_to_wigner_matrices():
    u = wigner.generators(B)
    np.testing.assert_array_equal(u, -u.transpose(0, 1, 3, 2))
    w = np.array([0.3, -1.1, 0.7])
    U = wigner.wigner_matrices(so3.exp(w), B)
    for l in range(B):  # noqa: E741
        expected = scipy.linalg.expm(sum(w[k] * _block(u[k, l], l) for k in range(3)))
        np.testing.assert_allclose(_block(U[l], l), expected, atol=1e-12)


def test_generators_match_finite_differences():
    eps = 1e-6
    u = wigner.generators(B)
    for k in range(3):
        e = np.zeros(3)
        e[k] = eps
        fd = wigner.wigner_matrices(so3.exp(e), B) - wigner.wigner_matrices(so3.exp(-e), B)
        np.testing.assert_allclose(fd / (2 * eps), u[k], atol=1e-8)


def test_casimir_identity():
    u = wigner.generators(B)
    casimir = np.einsum("klmn,klnp->lmp", u, u)
    for l in range(B):  # noqa: E741
        np.testing.assert_allclose(
            _block(casimir[l], l), -l * (l + 1) * np.eye(2 * l + 1), atol=1e-11
        )


def test_wigner_z_closed_form():
    angle = 0.83
    np.testing.assert_allclose(
        wigner.wigner_z(angle, B), wigner.wigner_matrices(so3.exp([0, 0, angle]), B), atol=1e-13
    )
