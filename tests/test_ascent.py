"""The compass search over rotations on the phase-correlation peak (o3d_spectral.search.ascent)."""

import numpy as np
import pytest

import o3d_spectral
from o3d_spectral.harness.real import load_cases
from o3d_spectral.search import Kind, situation
from o3d_spectral.search.ascent import best_ascent, peak_ascent
from o3d_spectral.search.candidates import placed_peaks, span_factor, turned_correlation
from o3d_spectral.spectra import so3


@pytest.fixture(scope="module")
def scans():
    """Dragon scans at 0 and 24 degrees (two single views, 5 mm voxels) and the truth."""
    case = load_cases(["dragon_24"])[0]
    stepper = o3d_spectral.SpectralStepper(case.target, 0.005)
    moving = stepper.moving(case.source)
    assert situation(stepper, moving).kind is Kind.TWO_SCANS
    return stepper, moving, case.T_gt


@pytest.mark.slow
@pytest.mark.parametrize("axis", [(1.0, 0.0, 0.0), (0.3, -0.8, 0.5)])
def test_ascent_turns_a_pose_15_degrees_off_back_to_the_truth(scans, axis):
    stepper, moving, truth = scans
    turn = so3.exp(np.deg2rad(15.0) * np.asarray(axis) / np.linalg.norm(axis))
    start = truth.copy()
    start[:3, :3] = turn @ truth[:3, :3]  # turned about the frame's origin: off in place too
    _, start_peak, _ = stepper.locate(moving, start[:3, :3])
    ascended = peak_ascent(stepper, moving, start)
    pose, peak = ascended.transformation(moving.centroid), ascended.translation_peak
    assert so3.is_rotation(pose[:3, :3], atol=1e-9) and np.array_equal(pose[3], [0, 0, 0, 1])
    assert np.rad2deg(so3.rotation_angle(pose[:3, :3].T @ truth[:3, :3])) < 3.0
    centroid = moving.centroid
    reached = pose[:3, :3] @ centroid + pose[:3, 3]
    assert np.linalg.norm(reached - (truth[:3, :3] @ centroid + truth[:3, 3])) < 0.005
    assert peak >= start_peak


def test_ascent_from_the_truth_stays_there(scans):
    stepper, moving, truth = scans
    pose = peak_ascent(stepper, moving, truth).transformation(moving.centroid)
    assert np.rad2deg(so3.rotation_angle(pose[:3, :3].T @ truth[:3, :3])) < 2.0


def test_peak_ascent_must_be_a_flag():
    with pytest.raises(TypeError, match="peak_ascent"):
        o3d_spectral.GlobalSearchOption(peak_ascent="yes")


def test_span_factor_coarsens_only_clouds_spanning_more_cells(scans):
    """The dragon scan (about 50 voxels across) keeps the voxel at 64 cells; asked for 10
    cells, the grid is 2 r / 10 voxels rounded up to half a voxel."""
    stepper, moving, _ = scans
    assert span_factor(stepper.voxel_size, moving.radius, 64.0) == 1.0
    across = 2.0 * moving.radius / stepper.voxel_size
    factor = span_factor(stepper.voxel_size, moving.radius, 10.0)
    assert factor % 0.5 == 0.0 and across / 10.0 <= factor < across / 10.0 + 0.5


def test_coarsened_grids_are_shared_and_only_the_last_few_kept(scans):
    stepper, _, _ = scans
    grid = stepper.grid
    first = grid.coarsened(2.0)
    assert grid.coarsened(2.0) is first and first.voxel_size == 2.0 * grid.voxel_size
    for factor in (2.5, 3.0, 3.5, 4.0):  # one more than are kept
        grid.coarsened(factor)
    assert grid.coarsened(2.0) is not first  # dropped, built again



@pytest.mark.slow
def test_the_global_call_ascends_between_two_scans():
    """Between two views the law's EGI term leaves the pose off: the ascent runs there."""
    case = load_cases(["dragon_24"])[0]
    search = o3d_spectral.GlobalSearchOption(confirm=False)
    result = o3d_spectral.registration_spectral_global(case.source, case.target, 0.005,
                                                       search=search)
    assert "ascent" in result.stage_times


def test_batched_placement_peaks_are_those_of_one_placement_each(scans):
    stepper, moving, truth = scans
    rotations = [truth[:3, :3], *so3.uniform_rotations(12)]
    for factor in (1.0, 3.0):
        one_each = [stepper.locate(moving, R, factor=factor)[1] for R in rotations]
        batched = placed_peaks(stepper, moving, rotations, factor)
        np.testing.assert_allclose(batched, one_each, rtol=1e-5)
        threaded = placed_peaks(stepper, moving, rotations, factor, workers=3)
        np.testing.assert_array_equal(threaded, batched)  # batches split alike on threads
        correlation, _ = turned_correlation(stepper, moving, factor)
        assert len(rotations) > correlation.backend.batch_size(correlation.shape)
    assert np.argmax(batched) == 0  # the truth places best


@pytest.mark.slow
def test_best_ascent_starts_from_the_pose_whose_coarse_ascent_peaks_highest(scans):
    stepper, moving, truth = scans
    starts = []
    for angle, axis in ((150.0, (0.0, 0.0, 1.0)), (15.0, (0.3, -0.8, 0.5))):
        start = truth.copy()
        turn = np.deg2rad(angle) * np.asarray(axis) / np.linalg.norm(axis)
        start[:3, :3] = so3.exp(turn) @ truth[:3, :3]
        starts.append(start)
    best = best_ascent(stepper, moving, starts).transformation(moving.centroid)
    assert np.rad2deg(so3.rotation_angle(best[:3, :3].T @ truth[:3, :3])) < 3.0
    alone = best_ascent(stepper, moving, starts[:1])  # one start: the full ascent from it
    np.testing.assert_array_equal(alone.rotation, peak_ascent(stepper, moving, starts[0]).rotation)
