"""The early confirmation of the global search (o3d_spectral.search.confirmation), the
situation that decides the stages, and the stage record of a call (o3d_spectral.common.stages)."""

import logging

import numpy as np
import open3d as o3d
import pytest

import o3d_spectral
from o3d_spectral.evidence import fit as fitting
from o3d_spectral.harness.errors import rotation_error, translation_error
from o3d_spectral.harness.metrics import instance_score
from o3d_spectral.search import Kind, confirmation, situation
from o3d_spectral.search.placement import Hypothesis
from o3d_spectral.spectra import so3
from o3d_spectral.synthetic.scenes import make_instance
from o3d_spectral.synthetic.suite import instance_rng
from tests.conftest import sample_model

VOXEL = 0.008


def turned(cloud, angle_deg, axis, shift):
    T = np.eye(4)
    T[:3, :3] = so3.exp(np.deg2rad(angle_deg) * np.asarray(axis) / np.linalg.norm(axis))
    T[:3, 3] = shift
    out = o3d.geometry.PointCloud(cloud)
    out.transform(T)
    return out, T


@pytest.fixture(scope="module")
def drill():
    """A power drill model (no symmetry) and a copy turned 130 degrees and moved 4 cm."""
    source = sample_model("power_drill", 20000)
    target, T = turned(source, 130.0, (0.2, -0.5, 0.8), (0.03, -0.02, 0.02))
    return source, target, T


def prepared(source, target):
    stepper = o3d_spectral.SpectralStepper(target, VOXEL)
    return stepper, stepper.moving(source)


def test_fit_is_whole_at_the_truth_and_low_half_a_turn_away(drill):
    source, target, T = drill
    stepper, moving = prepared(source, target)
    pose, share, close = fitting.fit(stepper, moving, target, T)
    assert share > 0.95 and close > 0.5
    assert rotation_error(pose, T) < 1.0
    flipped = T.copy()
    flipped[:3, :3] = T[:3, :3] @ so3.exp(np.array([0.0, 0.0, np.pi]))
    _, wrong, wrong_close = fitting.fit(stepper, moving, target, flipped)
    assert wrong < share - 0.1
    assert wrong_close < close


@pytest.mark.slow
def test_a_clear_case_is_confirmed_and_skips_the_climbs(drill):
    source, target, T = drill
    result = o3d_spectral.registration_spectral_global(source, target, VOXEL)
    assert result.confirmed
    assert list(result.stage_times) == ["prepare", "candidates", "confirm", "polish"]
    assert result.history == [] and result.converged
    assert result.fit >= confirmation.MIN_FIT and result.search_margin > 0.0
    center = np.asarray(source.points).mean(axis=0)
    assert rotation_error(result.transformation, T) < 1.0
    assert translation_error(result.transformation, T, center=center) < 0.002


@pytest.mark.slow
def test_without_confirmation_the_climbs_run_and_agree(drill):
    source, target, T = drill
    search = o3d_spectral.GlobalSearchOption(confirm=False)
    result = o3d_spectral.registration_spectral_global(source, target, VOXEL, search=search)
    assert not result.confirmed
    assert list(result.stage_times) == ["prepare", "candidates", "climbs", "polish"]
    assert rotation_error(result.transformation, T) < 1.0


def _decided(stepper, moving, target, T, best, *rivals):
    """confirm() on the truth and rivals 20 degrees away, their polish and measure given
    (``best``, ``rivals``: (share, close) each) through the ``fits`` record, by key."""
    truth = Hypothesis(
        T[:3, :3], T[:3, :3] @ moving.centroid + T[:3, 3], 0.5, 0.0, ("truth",))
    ranked, fits = [truth], {}
    fits[truth.key] = fitting.Fit(T, *best)
    for k, measures in enumerate(rivals):
        turn = so3.exp(np.array([0.0, np.deg2rad(20.0 + k), 0.0])) @ T[:3, :3]
        rival = Hypothesis(turn, truth.centre, 0.5, 0.0, ("rival", k))
        ranked.append(rival)
        fits[rival.key] = fitting.Fit(rival.transformation(moving.centroid), *measures)
    return confirmation.confirm(stepper, moving, target, ranked, fits=fits)


def test_a_pose_is_confirmed_when_it_fits_and_no_distinct_rival_is_closer(drill):
    source, target, T = drill
    stepper, moving = prepared(source, target)
    decided = _decided(stepper, moving, target, T, (0.9, 0.6))
    assert decided.confirmed and decided.runner_up == 0.0
    assert not _decided(stepper, moving, target, T, (0.7, 0.6)).confirmed  # under MIN_FIT
    closer = _decided(stepper, moving, target, T, (0.9, 0.6), (0.8, 0.5), (0.85, 0.61))
    assert not closer.confirmed and closer.runner_up == 0.85
    # a rival as close is a symmetry at the scale the data tells; one that fits more
    # points within a voxel but fewer within a quarter is a near-symmetry
    assert _decided(stepper, moving, target, T, (0.9, 0.6), (0.9, 0.6)).confirmed
    assert _decided(stepper, moving, target, T, (0.9, 0.6), (0.95, 0.5)).confirmed


def test_the_polish_brings_a_near_start_to_the_truth_and_confirms_it(drill):
    """A start 8 degrees off is polished to the truth's pose: no distinct rival."""
    source, target, T = drill
    stepper, moving = prepared(source, target)
    truth = Hypothesis(
        T[:3, :3], T[:3, :3] @ moving.centroid + T[:3, 3], 0.5, 0.0)
    near = Hypothesis(
        so3.exp(np.array([0.0, np.deg2rad(8.0), 0.0])) @ T[:3, :3], truth.centre, 0.5, 0.0)
    decided = confirmation.confirm(stepper, moving, target, [truth, near])
    assert decided.confirmed and decided.runner_up == 0.0


@pytest.mark.slow
def test_no_confirmation_in_a_scene():
    instance = make_instance("cluttered", "power_drill", rng=instance_rng(0, 3))
    stepper, moving = prepared(instance.source, instance.target)
    assert situation(stepper, moving).kind is Kind.SCENE  # where no fit confirms
    result = o3d_spectral.registration_spectral_global(instance.source, instance.target, VOXEL)
    assert "confirm" not in result.stage_times and not result.confirmed


def test_the_ascent_runs_between_two_views_only(drill):
    source, target, _ = drill
    search = o3d_spectral.GlobalSearchOption(confirm=False)
    result = o3d_spectral.registration_spectral_global(source, target, VOXEL, search=search)
    assert "ascent" not in result.stage_times  # a model against its copy: not two views


@pytest.mark.slow
def test_each_stage_logs_its_time_at_info(drill, caplog):
    source, target, _ = drill
    with caplog.at_level(logging.INFO, logger="o3d_spectral"):
        result = o3d_spectral.registration_spectral(source, target, VOXEL)
    lines = [r.getMessage() for r in caplog.records if r.name == "o3d_spectral"]
    assert [line.split(":")[0] for line in lines] == ["prepare", "law", "polish"]
    assert list(result.stage_times) == ["prepare", "law", "polish"]
    assert all(seconds >= 0.0 for seconds in result.stage_times.values())


def test_confirm_must_be_a_flag():
    with pytest.raises(TypeError, match="confirm"):
        o3d_spectral.GlobalSearchOption(confirm=1)


@pytest.mark.slow
def test_a_crop_into_its_scene_is_searched_as_an_object_in_a_scene():
    """The object's points cut out of a cluttered view, against the whole view: two single
    views, but not two scans of one thing. No sweep of SO(3) over the scene, no ascent;
    registered."""
    instance = make_instance("cluttered", "mustard_bottle", rng=instance_rng(0, 7))
    points = np.asarray(instance.target.points)[instance.target_labels == 0]
    crop = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    crop, T = turned(crop, 100.0, (1.0, 1.0, 0.0), (0.05, 0.0, 0.0))
    stepper, moving = prepared(crop, instance.target)
    assert moving.reading.view is not None and stepper.target_reading.view is not None
    assert situation(stepper, moving).kind is Kind.SCENE
    result = o3d_spectral.registration_spectral_global(crop, instance.target, VOXEL)
    assert "sweep" not in result.stage_times and "ascent" not in result.stage_times
    truth = np.linalg.inv(T)
    centre = np.asarray(crop.points).mean(axis=0)
    assert rotation_error(result.transformation, truth) < 2.0
    assert translation_error(result.transformation, truth, center=centre) < 0.005


def test_closer_needs_a_clear_lead_in_closeness():
    placed = fitting.Fit(np.eye(4), 0.5, 0.40)
    assert confirmation.closer(placed, fitting.Fit(np.eye(4), 0.9, 0.40 - 0.06))
    assert not confirmation.closer(placed, fitting.Fit(np.eye(4), 0.4, 0.40 - 0.04))


@pytest.mark.slow
def test_a_closer_placed_pose_is_returned_instead_of_the_climbed_one(monkeypatch):
    """An occluded banana: the climbs end on a wrong pose that the spectral score ranks
    first; the best placed pose, polished, lies clearly closer to the view and is right."""
    instance = make_instance("occluded", "banana", rng=instance_rng(0, 72))
    score = instance_score(instance)
    result = o3d_spectral.registration_spectral_global(instance.source, instance.target, VOXEL)
    assert not result.confirmed and score(np.asarray(result.transformation))[2]
    monkeypatch.setattr(confirmation, "CLOSER_MARGIN", 2.0)  # never closer: the climbs' pose
    climbed = o3d_spectral.registration_spectral_global(instance.source, instance.target, VOXEL)
    assert not score(np.asarray(climbed.transformation))[2]


def test_a_stage_outside_the_named_stages_is_refused():
    """Stage names are one list (``stages.GLOBAL_STAGES``, ``LOCAL_STAGES``) that the
    benchmarks read: a misspelt stage cannot slip into ``result.stage_times``."""
    from o3d_spectral.common.stages import GLOBAL_STAGES, StageClock

    clock = StageClock()
    with clock.stage(GLOBAL_STAGES[1]):
        pass
    assert list(clock.times) == ["candidates"]
    with pytest.raises(ValueError, match="unknown stage"), clock.stage("candidate"):
        pass


@pytest.mark.slow
def test_a_pose_that_may_be_wrong_gets_second_opinions():
    """A bowl 63% hidden by a panel: the adaptive search's best pose is wrong and warned;
    another climb's pose, climbed on and polished, is right and more confident, and is
    returned. Without second opinions (the default) the wrong pose is."""
    instance = make_instance("occluded", "bowl", rng=instance_rng(0, 1))
    score = instance_score(instance)
    result = o3d_spectral.registration_spectral_global(
        instance.source, instance.target, VOXEL,
        search=o3d_spectral.GlobalSearchOption(rotations="adaptive", second_opinions=3))
    assert "second_opinions" in result.stage_times
    assert score(np.asarray(result.transformation))[2]
    alone = o3d_spectral.registration_spectral_global(
        instance.source, instance.target, VOXEL,
        search=o3d_spectral.GlobalSearchOption(rotations="adaptive"))
    assert "second_opinions" not in alone.stage_times
    assert not score(np.asarray(alone.transformation))[2] and alone.confidence < 0.5
    assert result.confidence > alone.confidence


def test_a_confident_pose_gets_no_second_opinion(drill):
    source, target, _ = drill
    search = o3d_spectral.GlobalSearchOption(confirm=False, second_opinions=3)
    result = o3d_spectral.registration_spectral_global(source, target, VOXEL, search=search)
    assert result.confidence >= 0.5 and "second_opinions" not in result.stage_times


@pytest.mark.parametrize("count", [-1, 1.5, True])
def test_second_opinions_must_be_a_count(count):
    with pytest.raises((TypeError, ValueError), match="second_opinions"):
        o3d_spectral.GlobalSearchOption(second_opinions=count)
