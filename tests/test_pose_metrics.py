"""BOP's pose-error metrics against values worked out by hand on built cases."""

from __future__ import annotations

import numpy as np
import open3d as o3d
import pytest

from o3d_spectral.harness import pose_metrics as pm
from o3d_spectral.spectra import so3
from o3d_spectral.synthetic.symmetry import Symmetry

K = np.array([[600.0, 0.0, 320.0], [0.0, 600.0, 240.0], [0.0, 0.0, 1.0]])
SHAPE = (480, 640)
RADIUS, HEIGHT = 0.04, 0.1


def _pose(rotation: np.ndarray, translation) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = rotation, translation
    return T


def _about(axis, degrees: float) -> np.ndarray:
    return so3.exp(np.deg2rad(degrees) * np.asarray(axis, dtype=float))


def _cylinder() -> o3d.geometry.TriangleMesh:
    """A cylinder about z (r = 4 cm, 10 cm high, centred at the origin), 100 sides."""
    return o3d.geometry.TriangleMesh.create_cylinder(RADIUS, HEIGHT, resolution=100, split=1)


def _mug() -> o3d.geometry.TriangleMesh:
    """The cylinder with a handle: a 1 cm box on its side at +x, reaching r = 5 cm."""
    handle = o3d.geometry.TriangleMesh.create_box(0.012, 0.01, 0.03)
    handle.translate((RADIUS - 0.002, -0.005, -0.015))
    return _cylinder() + handle


def _rim(n: int = 400) -> np.ndarray:
    """Points on the cylinder's two rims (radius RADIUS at z = +-HEIGHT/2)."""
    angle = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    ring = np.stack([RADIUS * np.cos(angle), RADIUS * np.sin(angle), np.zeros(n)], axis=1)
    return np.concatenate([ring + (0, 0, HEIGHT / 2), ring - (0, 0, HEIGHT / 2)])


def test_cylinder_turned_about_its_axis_is_zero_with_the_continuous_symmetry():
    points = _rim()
    T_gt = _pose(_about((1, 0, 0), 30.0), (0.02, -0.01, 0.6))
    step = 360.0 / pm.CONTINUOUS_STEPS
    turn = 40 * step  # on BOP's sampling of the axis
    T_est = T_gt @ _pose(_about((0, 0, 1), turn), np.zeros(3))
    symmetry = Symmetry(axis=np.array([0.0, 0.0, 1.0]))
    assert pm.mssd(T_est, T_gt, points, symmetry) == pytest.approx(0.0, abs=1e-9)
    assert pm.mspd(T_est, T_gt, points, K, symmetry) == pytest.approx(0.0, abs=1e-6)
    # Off the sampling, at most half a step away: the chord of half a step.
    T_off = T_gt @ _pose(_about((0, 0, 1), 37.0), np.zeros(3))
    bound = 2 * RADIUS * np.sin(np.deg2rad(step / 4))
    assert pm.mssd(T_off, T_gt, points, symmetry) <= bound + 1e-12
    # Without the symmetry: every rim point moves along a chord, 2 r sin(turn / 2).
    chord = 2 * RADIUS * np.sin(np.deg2rad(turn / 2))
    assert pm.mssd(T_est, T_gt, points) == pytest.approx(chord, rel=1e-9)


def test_a_turn_the_view_cannot_see_is_accepted_by_vsd_alone():
    """The mug seen from the side opposite its handle, turned 18 degrees about its axis
    (5 of the cylinder's 100 facets): the handle stays behind the body, so every visible
    pixel is where it was: VSD 0. MSSD sees the handle move: its far corner, at
    r = sqrt(0.05^2 + 0.005^2), moves by the chord of 18 degrees."""
    mesh = _mug()
    # Camera looks along the model's +x (handle side away from the camera): model x is
    # the camera's z, model z the camera's y.
    facing = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
    T_gt = _pose(facing, (0.0, 0.0, 0.6))
    T_est = T_gt @ _pose(_about((0, 0, 1), 18.0), np.zeros(3))
    depth = pm.render_depth(mesh, T_gt, K, SHAPE)
    assert np.count_nonzero(depth) > 1000
    errors = pm.vsd(T_est, T_gt, mesh, depth, K, diameter=0.12)
    np.testing.assert_allclose(errors, 0.0, atol=1e-3)
    corner = np.hypot(RADIUS + 0.01, 0.005)
    points = np.asarray(mesh.vertices)
    assert pm.mssd(T_est, T_gt, points) == pytest.approx(
        2 * corner * np.sin(np.deg2rad(9.0)), rel=1e-6
    )
    assert pm.vsd_recall(errors[None]) == 1.0
    assert pm.mssd_recall([pm.mssd(T_est, T_gt, points)], [0.12]) < 1.0


def test_a_translated_pose_is_rejected_by_all_three():
    mesh = _cylinder()
    points = np.asarray(mesh.vertices)
    diameter = float(np.hypot(2 * RADIUS, HEIGHT))
    T_gt = _pose(_about((1, 0, 0), 90.0), (0.0, 0.0, 0.5))  # axis along the camera's y
    shift = 0.2  # more than the object is wide: the two images do not meet
    T_est = T_gt.copy()
    T_est[0, 3] += shift
    depth = pm.render_depth(mesh, T_gt, K, SHAPE)
    # MSSD: every point moves by the shift. MSPD: a point at depth z moves f * shift / z
    # pixels, the most for the nearest points (the front of the cylinder, z = 0.5 - r).
    e_mssd = pm.mssd(T_est, T_gt, points)
    e_mspd = pm.mspd(T_est, T_gt, points, K)
    assert e_mssd == pytest.approx(shift, rel=1e-12)
    z_near = 0.5 - RADIUS  # 100 sides: a vertex faces the camera
    assert e_mspd == pytest.approx(600.0 * shift / z_near, rel=1e-6)
    np.testing.assert_allclose(pm.vsd(T_est, T_gt, mesh, depth, K, diameter), 1.0)
    assert pm.mssd_recall([e_mssd], [diameter]) == 0.0  # 0.2 m > 0.5 diameters
    assert pm.mspd_recall([e_mspd], [640]) == 0.0  # > 50 px
    assert pm.vsd_recall(pm.vsd(T_est, T_gt, mesh, depth, K, diameter)[None]) == 0.0
    # A smaller shift: 0.22 diameters passes 6 of the 10 MSSD thresholds (0.25 .. 0.5),
    # and 600 * 0.22 d / z_near pixels passes those above it.
    small = 0.22 * diameter
    T_near = T_gt.copy()
    T_near[0, 3] += small
    assert pm.mssd_recall([pm.mssd(T_near, T_gt, points)], [diameter]) == pytest.approx(0.6)
    pixels = 600.0 * small / z_near
    expected = np.mean(np.array(pm.MSPD_THRESHOLDS_PX) > pixels)
    assert pm.mspd_recall([pm.mspd(T_near, T_gt, points, K)], [640]) == pytest.approx(expected)


def test_vsd_of_a_pose_moved_along_the_optical_axis():
    """A flat square (6.1 cm) facing the camera, moved 3.2 cm further away. Its image
    shrinks from 73 to 69 pixels a side (half-widths 0.0305 * 600 / 0.5 = 36.6 and
    0.0305 * 600 / 0.532 = 34.4 pixels about the principal point). Behind the test
    surface by more than delta, the estimate counts as visible only where the truth is,
    so the union is the truth's 73^2 pixels and 73^2 - 69^2 of them are unmatched; the
    matched ones are 3.2 cm (times the ray's length, under 1.002) apart: wrong for
    tau <= 0.3 of a 0.1 m diameter, right for tau >= 0.35."""
    square = o3d.geometry.TriangleMesh.create_box(0.061, 0.061, 1e-4)
    square.translate((-0.0305, -0.0305, 0.0))
    T_gt = _pose(np.eye(3), (0.0, 0.0, 0.5))
    T_est = _pose(np.eye(3), (0.0, 0.0, 0.532))
    depth = pm.render_depth(square, T_gt, K, SHAPE)
    assert np.count_nonzero(depth) == 73**2
    errors = pm.vsd(T_est, T_gt, square, depth, K, diameter=0.1)
    unmatched = (73**2 - 69**2) / 73**2
    expected = [1.0 if tau <= 0.3 else unmatched for tau in pm.VSD_TAUS]
    np.testing.assert_allclose(errors, expected, atol=1e-12)


def test_render_depth_of_a_plane_is_its_distance():
    square = o3d.geometry.TriangleMesh.create_box(0.1, 0.1, 1e-4)
    square.translate((-0.05, -0.05, 0.0))
    depth = pm.render_depth(square, _pose(np.eye(3), (0, 0, 0.7)), K, SHAPE)
    seen = depth[depth > 0]
    np.testing.assert_allclose(seen, 0.7, atol=1e-5)
    # 0.1 m at 0.7 m and f = 600: about 86 pixels a side.
    assert abs(np.sqrt(seen.size) - 600 * 0.1 / 0.7) < 2


def test_recalls_count_missing_estimates_as_wrong():
    assert pm.mssd_recall([np.nan, 0.0], [1.0, 1.0]) == 0.5
    assert pm.vsd_recall(np.full((2, 10), np.nan)) == 0.0
    assert pm.average_recall(1.0, 0.5, 0.0) == 0.5
    with pytest.raises(ValueError, match="errors must have shape"):
        pm.vsd_recall(np.zeros(3))
