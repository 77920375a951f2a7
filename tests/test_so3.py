import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from o3d_spectral.spectra import so3


def test_hat_is_cross_product(rng):
    w, v = rng.normal(size=3), rng.normal(size=3)
    np.testing.assert_allclose(so3.hat(w) @ v, np.cross(w, v), atol=1e-15)


@pytest.mark.parametrize("seed", range(20))
def test_exp_log_round_trip(seed):
    R = Rotation.random(random_state=seed).as_matrix()
    np.testing.assert_allclose(so3.exp(so3.log(R)), R, atol=1e-10)
    np.testing.assert_allclose(so3.exp(so3.log(R)), Rotation.from_rotvec(so3.log(R)).as_matrix())


@pytest.mark.parametrize("angle", [0.0, 1e-9, 1e-5, 1.0, np.pi - 1e-3, np.pi - 1e-7, np.pi])
def test_log_near_identity_and_half_turn(angle):
    axis = np.array([0.6, 0.0, 0.8])
    R = so3.exp(angle * axis)
    w = so3.log(R)
    assert np.linalg.norm(w) == pytest.approx(angle, abs=1e-7)
    np.testing.assert_allclose(so3.exp(w), R, atol=1e-9)


@pytest.mark.parametrize("seed", range(20))
def test_euler_zyz_round_trip(seed):
    R = Rotation.random(random_state=seed).as_matrix()
    alpha, beta, gamma = so3.euler_zyz(R)
    assert 0.0 <= beta <= np.pi
    np.testing.assert_allclose(so3.from_euler_zyz(alpha, beta, gamma), R, atol=1e-12)
    # scipy's intrinsic "ZYZ" is the same convention: R = Rz(a) Ry(b) Rz(g)
    np.testing.assert_allclose(
        Rotation.from_euler("ZYZ", [alpha, beta, gamma]).as_matrix(), R, atol=1e-12
    )


@pytest.mark.parametrize("beta", [0.0, np.pi])
def test_euler_zyz_gimbal_lock(beta):
    R = so3.from_euler_zyz(0.7, beta, -0.2)
    np.testing.assert_allclose(so3.from_euler_zyz(*so3.euler_zyz(R)), R, atol=1e-12)


def test_is_rotation_and_projection(rng):
    R = Rotation.random(random_state=1).as_matrix()
    assert so3.is_rotation(R)
    assert not so3.is_rotation(-R)
    assert not so3.is_rotation(2 * R)
    noisy = R + 1e-4 * rng.normal(size=(3, 3))
    P = so3.project_to_rotation(noisy)
    assert so3.is_rotation(P, atol=1e-12)
    assert np.linalg.norm(P - R) < 1e-3


rotation_vectors = st.lists(
    st.floats(-np.pi, np.pi, allow_nan=False, allow_infinity=False), min_size=3, max_size=3
).filter(lambda w: np.linalg.norm(w) < np.pi - 1e-6)


@pytest.mark.slow
@settings(max_examples=200, deadline=None)
@given(rotation_vectors)
def test_log_inverts_exp_inside_the_ball_of_radius_pi(w):
    np.testing.assert_allclose(so3.log(so3.exp(w)), w, atol=1e-8)
    assert so3.is_rotation(so3.exp(w), atol=1e-12)



def test_about_pivot_turns_about_the_pivot_then_shifts():
    rng = np.random.default_rng(5)
    R, T, pivot = so3.exp(rng.normal(size=3)), rng.normal(size=3), rng.normal(size=3)
    M = so3.about_pivot(R, T, pivot)
    np.testing.assert_allclose(M @ np.r_[pivot, 1.0], np.r_[pivot + T, 1.0], atol=1e-12)
    x = rng.normal(size=3)
    np.testing.assert_allclose(M[:3, :3] @ x + M[:3, 3], R @ (x - pivot) + pivot + T, atol=1e-12)
    np.testing.assert_array_equal(M[3], [0.0, 0.0, 0.0, 1.0])


def test_uniform_rotations_are_rotations_covering_so3_evenly():
    """1000 rotations: each a rotation, the same on every call, and every one of 5000
    random rotations within 23 degrees of one of them (the docstring's bound)."""
    from scipy.spatial.transform import Rotation

    swept = so3.uniform_rotations(1000)
    assert swept.shape == (1000, 3, 3)
    assert all(so3.is_rotation(R, atol=1e-12) for R in swept)
    np.testing.assert_array_equal(swept, so3.uniform_rotations(1000))
    probes = Rotation.random(5000, random_state=3).as_matrix()
    traces = np.einsum("mij,nij->mn", probes, swept).max(axis=1)
    nearest = np.rad2deg(np.arccos(np.clip((traces - 1.0) / 2.0, -1.0, 1.0)))
    assert nearest.max() < 23.0 and np.median(nearest) < 13.0
    # Even: no rotation of the set is another's near twin.
    own = np.einsum("mij,nij->mn", swept, swept)
    np.fill_diagonal(own, -1.0)
    assert np.rad2deg(np.arccos(np.clip((own.max(axis=1) - 1.0) / 2.0, -1.0, 1.0))).min() > 3.0
