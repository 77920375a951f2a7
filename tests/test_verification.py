"""The fit of the returned pose and of its distinct rivals
(o3d_spectral.evidence.verification), and the warnings on the calibrated confidence and on
ambiguity (o3d_spectral.evidence.diagnostics)."""

import logging

import numpy as np
import open3d as o3d
import pytest

import o3d_spectral
from o3d_spectral.evidence import diagnostics, verification
from o3d_spectral.harness.errors import rotation_error
from o3d_spectral.harness.metrics import instance_metrics
from o3d_spectral.spectra import so3
from o3d_spectral.synthetic.scenes import make_instance
from o3d_spectral.synthetic.suite import instance_rng
from tests.conftest import sample_model

VOXEL = 0.008


def turned(cloud, angle_deg, axis, shift):
    T = np.eye(4)
    T[:3, :3] = so3.exp(np.deg2rad(angle_deg) * np.asarray(axis) / np.linalg.norm(axis))
    T[:3, 3] = shift
    return o3d.geometry.PointCloud(cloud).transform(T), T


@pytest.fixture(scope="module")
def drill():
    """A power drill model (no symmetry) and a copy turned 150 degrees and moved."""
    source = sample_model("power_drill", 6000)
    target, T = turned(source, 150.0, (0.6, -0.48, 0.64), (0.05, 0.1, -0.02))
    return source, target, T


def about(T, angle_deg, axis):
    """``T`` turned further by ``angle_deg`` about ``axis`` (through the origin)."""
    out = T.copy()
    out[:3, :3] = T[:3, :3] @ so3.exp(np.deg2rad(angle_deg) * np.asarray(axis, dtype=float)
                                      / np.linalg.norm(axis))
    return out


def test_the_truth_fits_whole_a_wrong_pose_does_not(drill):
    source, target, T = drill
    stepper = o3d_spectral.SpectralStepper(target, VOXEL)
    moving = stepper.moving(source)
    fit, rival = verification.verify(stepper, moving, target, T, culls=False)
    assert fit > 0.95 and rival == 0.0
    flipped = about(T, 180.0, (1.0, 0.0, 0.0))  # upside down
    wrong, _ = verification.verify(stepper, moving, target, flipped, culls=False)
    assert wrong < 0.7
    # the flipped pose is a distinct rival of the truth; a start 4 degrees off is not
    _, rival = verification.verify(stepper, moving, target, T, [flipped], culls=False)
    assert rival == pytest.approx(wrong)
    _, rival = verification.verify(stepper, moving, target, T, [about(T, 4.0, (1, 0, 0))],
                                      culls=False)
    assert rival == 0.0


def test_a_right_global_result_fits_and_is_not_flagged(drill):
    source, target, T = drill
    result = o3d_spectral.registration_spectral_global(source, target, VOXEL)
    assert rotation_error(result.transformation, T) < 2.0
    assert result.fit > 0.95 and result.rival_fit < result.fit - 0.2
    assert result.confidence > 0.9
    assert not any("may be wrong" in w for w in result.warnings)


def test_a_wrong_local_result_is_flagged(drill, caplog):
    """The local law from the identity, 150 degrees away, ends wrong: warned, by its
    confidence."""
    source, target, T = drill
    with caplog.at_level(logging.WARNING, logger="o3d_spectral"):
        result = o3d_spectral.registration_spectral(source, target, VOXEL)
    assert rotation_error(result.transformation, T) > 10.0
    assert result.fit < 0.7 and result.rival_fit == 0.0
    assert result.confidence < diagnostics.WARN_BELOW
    flagged = [w for w in result.warnings if "may be wrong" in w]
    assert len(flagged) == 1
    assert flagged[0] in [r.getMessage() for r in caplog.records]


def test_a_model_right_on_a_single_view_fits_though_its_fitness_is_low():
    """Open3D's fitness counts the model's back, which the view cannot hold, as missed;
    the fit counts what the view's sensor would see."""
    instance = make_instance("partial", "power_drill", rng=instance_rng(0, 5))
    result = o3d_spectral.registration_spectral_global(instance.source, instance.target, VOXEL)
    assert instance_metrics(result.transformation, instance)["success"]
    assert result.fitness < 0.7
    assert result.fit >= 0.7 and result.confidence > 0.5
    assert not any("may be wrong" in w for w in result.warnings)


@pytest.mark.parametrize(("confidence", "flagged"), [
    (0.99, False), (0.5, False), (0.499, True), (0.0, True),
])
def test_the_warning_fires_under_half_confidence_only(confidence, flagged):
    assert diagnostics.may_be_wrong(confidence) == flagged
    reading = o3d_spectral.io.cloud.CloudReading()
    found, notes = diagnostics.registration_messages(
        converged=True, max_iteration=100, readings={"source": reading},
        confidence=confidence)
    assert notes == []
    assert [w.startswith(f"low confidence {confidence:.2f}") and "may be wrong" in w
            for w in found] == ([True] if flagged else [])


def test_the_ambiguity_warning_names_the_angle():
    """A rival the source does not show to be its symmetry is warned about; one that
    turns the whole source onto itself is a note: both poses are right."""
    reading = o3d_spectral.io.cloud.CloudReading()
    found, notes = diagnostics.registration_messages(
        converged=True, max_iteration=100, readings={"source": reading}, confidence=0.9,
        ambiguity=179.6)
    assert found == ["ambiguous: a pose 180 deg away fits as well (a symmetric object?): "
                     "result.ambiguity, result.ambiguous_transformation"] and notes == []
    found, notes = diagnostics.registration_messages(
        converged=True, max_iteration=100, readings={"source": reading}, confidence=0.9,
        ambiguity=179.6, symmetric_rival=True)
    assert found == [] and notes == ["symmetric: a pose 180 deg away fits as well, the "
                                     "source turned onto itself: both are right "
                                     "(result.ambiguity)"]


def test_the_local_call_has_no_rival():
    """The local call climbs one pose: nothing to compare it with."""
    source = sample_model("mustard_bottle", 4000)
    target, _ = turned(source, 10.0, (0.0, 0.0, 1.0), (0.01, 0.0, 0.0))
    result = o3d_spectral.registration_spectral(source, target, VOXEL)
    assert result.rival_fit == 0.0 and result.fit > 0.95


def test_a_free_motion_is_a_note_where_it_is_a_symmetry_and_a_warning_where_not():
    """A free turn the whole source does not resist (a can about its axis): a note; a
    free slide it resists (a box along the one face two views share): a warning."""
    from o3d_spectral.evidence.free_motions import FreeMotion

    reading = o3d_spectral.io.cloud.CloudReading()
    turn = FreeMotion("turn", np.array([0.0, 0.0, 1.0]), np.zeros(3), (-180.0, 180.0), True)
    slide = FreeMotion("slide", np.array([1.0, 0.0, 0.0]), np.zeros(3), (-0.04, 0.05), False)
    found, notes = diagnostics.registration_messages(
        converged=True, max_iteration=100, readings={"source": reading}, confidence=0.9,
        free_motions=(turn, slide))
    assert notes == ["free: the clouds fit as well turned about an axis along (0.00, 0.00, "
                     "1.00) by -180 to 180 deg, a symmetry of the source: the pose is right "
                     "up to it (result.free_motions)"]
    assert found == ["underdetermined: the clouds fit as well slid along (1.00, 0.00, 0.00) "
                     "by -0.04 to 0.05 m, which is no symmetry of the source: the data do "
                     "not fix the pose along it (result.free_motions)"]


def test_a_free_turn_of_a_single_view_is_a_symmetry_of_what_it_shows_only():
    """A view does not show the whole object: the note says the pose is right up to the
    turn only where the object shares the view's symmetry (a mug's hidden handle)."""
    from o3d_spectral.evidence.free_motions import FreeMotion

    view = o3d_spectral.io.cloud.CloudReading(view=np.array([0.0, 0.0, 1.0]))
    turn = FreeMotion("turn", np.array([0.0, 0.0, 1.0]), np.zeros(3), (-180.0, 180.0), True)
    found, notes = diagnostics.registration_messages(
        converged=True, max_iteration=100, readings={"source": view}, confidence=0.9,
        free_motions=(turn,))
    assert found == []
    assert notes == ["free: the clouds fit as well turned about an axis along (0.00, 0.00, "
                     "1.00) by -180 to 180 deg, a symmetry of the source as its view shows "
                     "it: the pose is right up to it where the object has that symmetry too "
                     "(a can), not where a part out of sight breaks it (a mug's handle) "
                     "(result.free_motions)"]
