"""The search's placements, batched: each candidate where one phase correlation puts it."""

import numpy as np
import pytest

import o3d_spectral
from o3d_spectral.search.candidates import egi_candidates
from o3d_spectral.search.placement import Placements, place, placement_factor
from o3d_spectral.synthetic.scenes import make_instance

VOXEL = 0.008


def setting(condition):
    """The stepper, the moving cloud and the first 12 EGI candidates of one instance."""
    instance = make_instance(condition, "power_drill", rng=np.random.default_rng(1))
    stepper = o3d_spectral.SpectralStepper(instance.target, VOXEL)
    moving = stepper.moving(instance.source)
    candidates = egi_candidates(stepper, moving, o3d_spectral.GlobalSearchOption())[:12]
    return stepper, moving, candidates


def assert_placed_as_located(stepper, moving, candidates, around, factor=1.0):
    """Each placed hypothesis is where ``locate`` puts its rotation: centre to 1e-4 voxel,
    peak height to 1e-5, ``J_t`` to 1e-6 (single precision's rounding)."""
    placed = place(stepper, moving, candidates, Placements(), around=around, workers=2)
    assert len(placed) == len(candidates)
    for hypothesis in placed:
        centre, peak, cost = stepper.locate(moving, hypothesis.rotation, around=around,
                                            factor=factor)
        np.testing.assert_allclose(hypothesis.centre, centre, rtol=0, atol=1e-4 * VOXEL * factor)
        assert hypothesis.translation_peak == pytest.approx(peak, rel=1e-5)
        assert hypothesis.cost_translation == pytest.approx(cost, abs=1e-6)
    assert [h.translation_peak for h in placed] == sorted(
        (h.translation_peak for h in placed), reverse=True)
    return placed


def test_placements_in_a_scene_are_one_correlation_each_anywhere_and_in_a_window():
    stepper, moving, candidates = setting("cluttered")
    placed = assert_placed_as_located(stepper, moving, candidates, None)
    around = placed[0].centre
    block = stepper.grid.search_box(moving.radius, around)
    assert block is not stepper.grid.box  # a window of the scene, padded
    box = stepper.grid.moving_box(moving.radius, moving.centroid)
    assert stepper.grid.searched(block, box, moving.radius) is None
    assert_placed_as_located(stepper, moving, candidates, around)


def test_placements_in_a_window_on_its_own_fft_read_only_the_shifts_inside_it():
    stepper, moving, candidates = setting("full")
    around = moving.centroid + [0.01, -0.02, 0.005]
    block = stepper.grid.search_box(moving.radius, around)
    box = stepper.grid.moving_box(moving.radius, moving.centroid)
    assert block is not stepper.grid.box
    assert stepper.grid.searched(block, box, moving.radius) is not None
    assert_placed_as_located(stepper, moving, candidates, around)


def test_placements_between_two_scans_on_the_coarser_placement_grid():
    stepper, moving, candidates = setting("partial")
    factor = placement_factor(VOXEL, moving.radius, two_scans=True)
    placed = place(stepper, moving, candidates, Placements(), two_scans=True, workers=1)
    for hypothesis in placed:
        centre, peak, _ = stepper.locate(moving, hypothesis.rotation, factor=factor)
        np.testing.assert_allclose(hypothesis.centre, centre, rtol=0, atol=1e-4 * VOXEL * factor)
        assert hypothesis.translation_peak == pytest.approx(peak, rel=1e-5)
