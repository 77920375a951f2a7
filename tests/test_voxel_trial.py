"""The voxel size chosen by trial (o3d_spectral.voxel_by_trial)."""

import numpy as np
import pytest

import o3d_spectral
from o3d_spectral import voxel_by_trial as trial_module
from o3d_spectral.synthetic.sampling import model_cloud, point_cloud
from o3d_spectral.synthetic.scenes import make_instance


@pytest.fixture(scope="module")
def drill_view():
    return make_instance("partial", "power_drill", rng=np.random.default_rng(7))


@pytest.mark.parametrize("ladder", [(), (1.0, 0.0), (1.0, -2.0), (float("nan"),)])
def test_a_ladder_without_positive_factors_is_refused(drill_view, ladder):
    with pytest.raises(ValueError, match="ladder"):
        o3d_spectral.voxel_trial(drill_view.source, drill_view.target, ladder=ladder)


def test_a_confident_first_size_ends_the_ladder(drill_view):
    rule = o3d_spectral.suggest_voxel_size(drill_view.source, drill_view.target)
    trial = o3d_spectral.voxel_trial(drill_view.source, drill_view.target)
    assert trial.result.confidence >= trial_module.CONFIDENT
    assert trial.tried == [(rule, trial.result.confidence)]
    assert trial.voxel_size == rule
    again = o3d_spectral.registration_spectral_global(drill_view.source, drill_view.target,
                                                      rule)
    np.testing.assert_array_equal(trial.result.transformation, again.transformation)


def test_without_a_confident_size_every_size_is_tried_and_the_most_confident_kept(drill_view):
    """Every pose of another model on the drill's view is wrong: none is confident."""
    other = point_cloud(*(a.copy() for a in model_cloud("mug", 6000)))
    ladder = (1.0, 1.5)
    trial = o3d_spectral.voxel_trial(other, drill_view.target, ladder=ladder)
    rule = o3d_spectral.suggest_voxel_size(other, drill_view.target)
    assert [v for v, _ in trial.tried] == pytest.approx([rule * f for f in ladder], rel=1e-12)
    confidences = [c for _, c in trial.tried]
    assert max(confidences) < trial_module.CONFIDENT
    assert trial.result.confidence == max(confidences)
    assert trial.voxel_size == trial.tried[int(np.argmax(confidences))][0]


def test_the_options_reach_every_registration(drill_view):
    search = o3d_spectral.GlobalSearchOption(hypotheses=2, climbs=1, confirm=False)
    trial = o3d_spectral.voxel_trial(drill_view.source, drill_view.target, ladder=(1.0,),
                                     search=search)
    alone = o3d_spectral.registration_spectral_global(
        drill_view.source, drill_view.target, trial.voxel_size, search=search)
    np.testing.assert_array_equal(trial.result.transformation, alone.transformation)
    assert not trial.result.confirmed
