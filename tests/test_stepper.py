"""The stepper: the fixed spectra, the windowed translation search, the focused EGI and
the rotation correlation over SO(3)."""

from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import o3d_spectral
from o3d_spectral.spectra.egi import harmonics_table
from tests.conftest import sample_model, thin_walled_cup


def test_stepper_rejects_bad_voxel_size():
    with pytest.raises(ValueError, match="voxel_size"):
        o3d_spectral.SpectralStepper(np.zeros((100, 3)), 0.0)


def _object_on_a_wide_plane(shift):
    """A drill (2000 points) moved by ``shift`` metres, on a 1.2 m x 1.2 m plane of points
    (a small object in a large scene), as arrays (N, 6) with normals."""
    drill = sample_model("power_drill", 2000)
    obj = np.hstack([np.asarray(drill.points) + shift, np.asarray(drill.normals)])
    u = np.linspace(-0.6, 0.6, 121)
    x, y = np.meshgrid(u, u)
    plane = np.column_stack([x.ravel(), y.ravel(), np.full(x.size, -0.15)])
    normals = np.tile([0.0, 0.0, 1.0], (len(plane), 1))
    return drill, np.vstack([obj, np.hstack([plane, normals])])


def test_windowed_search_finds_the_global_shift_on_a_smaller_grid():
    shift = np.array([0.23, -0.17, 0.05])
    drill, scene = _object_on_a_wide_plane(shift)
    stepper = o3d_spectral.SpectralStepper(scene, 0.008)
    moving = stepper.moving(drill)
    whole = stepper.evaluate(moving)
    np.testing.assert_allclose(whole.translation, shift, atol=0.15 * 0.008)  # sub-voxel
    expected = moving.centroid + shift
    window = stepper.grid.search_box(moving.radius, around=expected + 0.01)
    assert np.prod(window.shape) < np.prod(stepper.grid.box.shape) / 4
    windowed = stepper.evaluate(moving, around=expected + 0.01)
    np.testing.assert_allclose(windowed.translation, whole.translation, atol=0.05 * 0.008)
    # Without a prediction, or with the window off, the whole grid is searched.
    assert stepper.grid.search_box(moving.radius) is stepper.grid.box
    off = o3d_spectral.SpectralStepper(
        scene, 0.008, option=o3d_spectral.SpectralRegistrationOption(translation_window=None)
    )
    assert off.grid.search_box(off.moving(drill).radius, around=expected) is off.grid.box


def test_window_is_used_where_it_shrinks_the_fft_and_agrees_with_the_whole_grid():
    """An object against itself: the block about the prediction (its own FFT size) is
    smaller than the padded whole grid, and reads the same shift."""
    drill = sample_model("power_drill", 2000)
    shift = np.array([0.012, -0.021, 0.005])
    stepper = o3d_spectral.SpectralStepper(drill, 0.008)
    moving = stepper.moving(np.asarray(drill.points) - shift)
    window = stepper.grid.search_box(moving.radius, around=moving.centroid + shift)
    assert window is not stepper.grid.box
    box = stepper.grid.moving_box(moving.radius, moving.centroid)
    whole_fft = stepper.grid.fft_shape(stepper.grid.box, box)
    assert np.prod(stepper.grid.fft_shape(window, box, moving.radius)) < np.prod(whole_fft)
    whole = stepper.evaluate(moving)
    windowed = stepper.evaluate(moving, around=moving.centroid + shift)
    np.testing.assert_allclose(whole.translation, shift, atol=0.1 * 0.008)
    np.testing.assert_allclose(windowed.translation, shift, atol=0.1 * 0.008)


def test_window_is_not_used_where_it_would_not_shrink_the_fft():
    """A small fixed patch: the whole grid plus the moving one is smaller than a block
    of the moving grid's size plus the window."""
    drill = sample_model("power_drill", 2000)
    points = np.asarray(drill.points)
    patch = points[np.linalg.norm(points - points[0], axis=1) < 0.03]
    stepper = o3d_spectral.SpectralStepper(patch, 0.008)
    moving = stepper.moving(drill)
    assert stepper.grid.search_box(moving.radius, around=moving.centroid) is stepper.grid.box


def test_focused_egi_is_that_of_the_normals_in_the_ball():
    drill = sample_model("power_drill", 2000)
    shift = np.array([0.3, 0.2, 0.0])
    obj = np.hstack([np.asarray(drill.points) + shift, np.asarray(drill.normals)])
    u = np.linspace(-0.6, 0.6, 61)
    x, y = np.meshgrid(u, u)
    plane = np.column_stack([x.ravel(), y.ravel(), np.full(x.size, -0.6)])
    scene = np.vstack([obj, np.hstack([plane, np.tile([0.0, 0.0, 1.0], (len(plane), 1))])])
    stepper = o3d_spectral.SpectralStepper(scene, 0.008)
    alone = o3d_spectral.SpectralStepper(obj, 0.008)
    centre = obj[:, :3].mean(axis=0)
    radius = np.linalg.norm(obj[:, :3] - centre, axis=1).max() + 0.01
    focused = stepper.focused(centre[None, :], radius)
    assert focused is not stepper
    for level in range(stepper.levels):
        np.testing.assert_allclose(
            focused.target_coefficients[level], alone.target_coefficients[level], atol=1e-12
        )
        assert not np.allclose(stepper.target_coefficients[level], alone.target_coefficients[level])
    assert focused.grid is stepper.grid  # the translation search is shared
    # A fixed cloud that is all in the ball has nothing to focus on.
    assert alone.focused(centre[None, :], radius) is alone
    # Near the object's own points: the same normals.
    near = stepper.focused(obj[:, :3], 0.001)
    np.testing.assert_allclose(near.target_coefficients[-1], alone.target_coefficients[-1])


def test_visible_correlation_ranks_the_rotation_of_a_view_first():
    """A power drill seen from one side (stored): the
    whole model's EGI correlation puts the right rotation 7th among its peaks; weighted
    and normalised as the sensor sees it (``search_visibility``), it is the first."""
    from o3d_spectral.harness.errors import symmetric_rotation_error
    from o3d_spectral.spectra.so3fft import peaks
    from tests.scene_fixtures import load_scene

    instance = load_scene("partial_power_drill")
    ranks = {}
    for visibility in (True, False):
        stepper = o3d_spectral.SpectralStepper(instance.target, 0.008)
        assert stepper.viewpoint is not None
        moving = stepper.moving(instance.source)
        errors = []
        grid = stepper.rotation_grid(moving, 64, visibility=visibility)
        for R, _ in peaks(grid, count=8):
            estimate = np.eye(4)
            estimate[:3, :3] = R
            errors.append(symmetric_rotation_error(estimate, instance.T_gt, instance.symmetry))
        right = np.flatnonzero(np.asarray(errors) < 15.0)
        ranks[visibility] = int(right[0]) if len(right) else None
    assert ranks == {True: 0, False: 6}


def test_a_two_sided_cloud_is_seen_from_either_side():
    """A thin-walled cup against a view of its inside from above: none of the cup's
    points is culled, each normal is turned to face the sensor, and the law's evaluation
    does not depend on the signs of the cup's normals (the table of harmonics and the
    normals projected anew agree)."""
    points, normals = thin_walled_cup(wall=0.002)
    inside = (normals[:, 2] > 0.5) | (np.einsum("ij,ij->i", points, normals) < 0.0)
    T = np.array([0.3, 0.1, 0.9])
    view = np.hstack([points[inside] + T, normals[inside]])
    sensor = o3d_spectral.CloudOption(target_viewpoint=tuple(T + [0.0, 0.0, 0.5]))
    stepper = o3d_spectral.SpectralStepper(view, 0.008, cloud=sensor)
    moving = stepper.moving(np.hstack([points, normals]))
    assert moving.reading.two_sided and moving.harmonics is not None
    R = Rotation.from_rotvec([0.3, -0.2, 0.1]).as_matrix()
    _, toward, cosine = stepper.visible(moving, R, T)
    assert toward.all() and np.mean(cosine < 0.0) > 0.2  # seen from behind, kept
    one_sided = replace(moving, reading=replace(moving.reading, two_sided=False))
    assert not stepper.visible(one_sided, R, T)[1].all()
    flips = np.random.default_rng(7).choice([-1.0, 1.0], size=(len(moving.point_normals), 1))
    flipped = moving.point_normals * flips
    variants = [replace(moving, harmonics=None),
                replace(moving, point_normals=flipped, harmonics=harmonics_table(flipped, 16))]
    expected = stepper.evaluate(moving, R, T)
    for variant in variants:
        found = stepper.evaluate(variant, R, T)
        np.testing.assert_allclose(found.rotation, expected.rotation, atol=1e-10)
        assert found.correlation == pytest.approx(expected.correlation, abs=1e-12)
