"""The voxel size chosen by trial (o3d_spectral.voxel.by_trial)."""

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import o3d_spectral
from o3d_spectral.synthetic.sampling import model_cloud, point_cloud
from o3d_spectral.synthetic.scenes import make_instance
from o3d_spectral.voxel import by_trial as trial_module


@pytest.fixture(scope="module")
def drill_view():
    return make_instance("partial", "power_drill", rng=np.random.default_rng(7))


@pytest.mark.parametrize("ladder", [(), (1.0, 0.0), (1.0, -2.0), (float("nan"),)])
def test_a_ladder_without_positive_factors_is_refused(drill_view, ladder):
    with pytest.raises(ValueError, match="ladder"):
        o3d_spectral.voxel_trial(drill_view.source, drill_view.target, ladder=ladder)


@pytest.mark.parametrize("ladder", [None, "1.0", 1.5, [[1.0]], [1.0, "x"]])
def test_a_ladder_that_is_not_a_sequence_of_numbers_is_named(drill_view, ladder):
    with pytest.raises((TypeError, ValueError), match="^ladder must be"):
        o3d_spectral.voxel_trial(drill_view.source, drill_view.target, ladder=ladder)


def test_two_sizes_agreeing_end_the_ladder(drill_view):
    rule = o3d_spectral.suggest_voxel_size(drill_view.source, drill_view.target)
    trial = o3d_spectral.voxel_trial(drill_view.source, drill_view.target)
    assert [v for v, _ in trial.tried] == pytest.approx(
        [rule * f for f in trial_module.VOXEL_LADDER[:2]], rel=1e-12)
    assert trial.agreed
    assert trial.voxel_size == min(v for v, _ in trial.tried)  # the finer of the two
    again = o3d_spectral.registration_spectral_global(drill_view.source, drill_view.target,
                                                      trial.voxel_size)
    np.testing.assert_array_equal(trial.result.transformation, again.transformation)


def test_without_agreement_every_size_is_tried(drill_view):
    """Every pose of another model on the drill's view is wrong: none settles the ladder."""
    other = point_cloud(*(a.copy() for a in model_cloud("mug", 6000)))
    ladder = (1.0, 1.5)
    trial = o3d_spectral.voxel_trial(other, drill_view.target, ladder=ladder)
    rule = o3d_spectral.suggest_voxel_size(other, drill_view.target)
    assert [v for v, _ in trial.tried] == pytest.approx([rule * f for f in ladder], rel=1e-12)
    assert trial.voxel_size in [v for v, _ in trial.tried]


def test_the_options_reach_every_registration(drill_view):
    search = o3d_spectral.GlobalSearchOption(hypotheses=2, climbs=1, confirm=False)
    trial = o3d_spectral.voxel_trial(drill_view.source, drill_view.target, ladder=(1.0,),
                                     search=search)
    alone = o3d_spectral.registration_spectral_global(
        drill_view.source, drill_view.target, trial.voxel_size, search=search)
    np.testing.assert_array_equal(trial.result.transformation, alone.transformation)
    assert not trial.result.confirmed


# The choice among sizes, on stand-in registrations: each factor of the ladder returns
# a pose turned by ``degrees`` about z, with its confidence and ambiguity.

def _stand_in(monkeypatch, outcomes):
    """Make the trial's registration at rule * factor return ``outcomes[factor]``:
    (degrees, confidence, ambiguous); return the factors registered, in order."""
    monkeypatch.setattr(trial_module, "suggest_voxel_size", lambda source, target: 1.0)
    called = []

    def register(source, target, voxel_size, **options):
        called.append(voxel_size)
        degrees, confidence, ambiguous = outcomes[voxel_size]
        pose = np.eye(4)
        pose[:3, :3] = Rotation.from_euler("z", degrees, degrees=True).as_matrix()
        return SimpleNamespace(transformation=pose, confidence=confidence,
                               ambiguity=170.0 if ambiguous else None)

    monkeypatch.setattr(trial_module, "registration_spectral_global", register)
    return called


def test_agreeing_sizes_stop_and_keep_the_finer(monkeypatch):
    """The same pose at two sizes: the finer size's polish, however confident the other."""
    called = _stand_in(monkeypatch, {1.0: (0.0, 0.87, False), 2.0: (3.0, 0.90, False),
                                     0.5: (120.0, 0.92, False)})
    trial = trial_module.voxel_trial(None, None, ladder=(1.0, 2.0, 0.5))
    assert called == [1.0, 2.0]
    assert trial.voxel_size == 1.0 and trial.agreed


def test_of_two_agreeing_sizes_one_warned_about_the_other_is_kept(monkeypatch):
    called = _stand_in(monkeypatch, {1.0: (0.0, 0.4, False), 2.0: (3.0, 0.9, False),
                                     0.5: (120.0, 0.92, False)})
    trial = trial_module.voxel_trial(None, None, ladder=(1.0, 2.0, 0.5))
    assert called == [1.0, 2.0]
    assert trial.voxel_size == 2.0 and trial.agreed


def test_agreeing_sizes_that_may_be_wrong_do_not_stop(monkeypatch):
    called = _stand_in(monkeypatch, {1.0: (0.0, 0.01, False), 2.0: (3.0, 0.02, False),
                                     0.5: (90.0, 0.9, False)})
    trial = trial_module.voxel_trial(None, None, ladder=(1.0, 2.0, 0.5))
    assert called == [1.0, 2.0, 0.5]
    assert trial.voxel_size == 0.5 and not trial.agreed


def test_the_last_size_votes_and_unambiguous_votes_count_first(monkeypatch):
    """Two sizes on one ambiguous pose, one on an unambiguous pose, all as confident:
    the unambiguous pose is kept; the votes also decide where the last size agrees."""
    called = _stand_in(monkeypatch, {1.0: (40.0, 1.0, True), 2.0: (0.0, 1.0, False),
                                     0.5: (44.0, 1.0, True)})
    trial = trial_module.voxel_trial(None, None, ladder=(1.0, 2.0, 0.5))
    assert called == [1.0, 2.0, 0.5]
    assert trial.voxel_size == 2.0 and not trial.agreed
    assert trial.tried == [(1.0, 1.0), (2.0, 1.0), (0.5, 1.0)]


def test_among_unambiguous_poses_the_pool_of_more_sizes_wins(monkeypatch):
    _stand_in(monkeypatch, {1.0: (0.0, 0.6, False), 2.0: (90.0, 0.95, False),
                            0.5: (2.0, 0.6, False)})
    trial = trial_module.voxel_trial(None, None, ladder=(1.0, 2.0, 0.5))
    assert trial.voxel_size == 1.0 and trial.agreed  # 0.6 + 0.6 against 0.95


def test_one_size_is_kept_as_it_is(monkeypatch):
    called = _stand_in(monkeypatch, {1.0: (0.0, 0.1, True)})
    trial = trial_module.voxel_trial(None, None, ladder=(1.0,))
    assert called == [1.0] and trial.voxel_size == 1.0 and not trial.agreed


def test_a_vote_that_may_be_wrong_is_not_decisive(monkeypatch):
    """Two sizes right up to a symmetry (ambiguous, far apart), one unambiguous and wrong
    at almost no confidence: a right pose is kept."""
    _stand_in(monkeypatch, {1.0: (0.0, 1.0, True), 2.0: (120.0, 1.0, True),
                            0.5: (170.0, 1e-4, False)})
    trial = trial_module.voxel_trial(None, None, ladder=(1.0, 2.0, 0.5))
    assert trial.voxel_size == 1.0
