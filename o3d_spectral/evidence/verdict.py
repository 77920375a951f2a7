"""The verdict on a returned pose: everything a result says about it, measured once.

After the polish, one stage takes the pose, in the frame the run works in (the moving
cloud, the fixed cloud centred on the target), and measures it:

1. its fit, and the best distinct pose among the search's hypotheses and the pose's own
   turns (:func:`o3d_spectral.evidence.verification.measure`,
   :func:`~o3d_spectral.evidence.verification.ambiguity`);
2. its evidence (:func:`o3d_spectral.evidence.pose.pose_evidence`), its free motions
   among it;
3. the calibrated confidence (:mod:`o3d_spectral.evidence.confidence`);
4. the call's warnings and notes (:mod:`o3d_spectral.evidence.diagnostics`).

The caller moves what it holds to its own frame once (:mod:`o3d_spectral.run`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import open3d as o3d
from numpy.typing import NDArray

from ..io.cloud import CloudReading
from ..law.stepper import MovingCloud, SpectralStepper
from .confidence import confidence
from .diagnostics import registration_messages
from .free_motions import FreeMotion
from .pose import PoseEvidence, pose_evidence
from .verification import FixedPoints, ambiguity, measure

__all__ = ["Verdict", "verdict"]


@dataclass(frozen=True)
class Verdict:
    """What a result says about its pose (see the module docstring).

    Attributes
    ----------
    fit : float
        The pose's fit, [0, 1] (``result.fit``).
    rival_fit : float
        The best fit of a distinct hypothesis measured here, [0, 1].
    ambiguity : float or None
        The angle to a distinct pose that fits as well, degrees; None where none does.
    rival : ndarray, shape (4, 4), or None
        That pose, in the frame of the pose judged; None where none fits as well.
    evidence : PoseEvidence
        The pose's evidence; its free motions in the run's frame.
    confidence : float
        The calibrated probability that the pose is right, [0, 1].
    warnings, notes : list of str
        The call's warnings and notes, logged.
    """

    fit: float
    rival_fit: float
    ambiguity: float | None
    rival: NDArray[np.float64] | None
    evidence: PoseEvidence
    confidence: float
    warnings: list[str]
    notes: list[str]

    @property
    def free_motions(self) -> tuple[FreeMotion, ...]:
        """The pose's free motions, in the run's frame."""
        return self.evidence.free_motions


def verdict(
    stepper: SpectralStepper, moving: MovingCloud, fixed: o3d.geometry.PointCloud,
    pose: NDArray[np.float64], others: list[NDArray[np.float64]], *, culls: bool,
    readings: dict[str, CloudReading], converged: bool, max_iteration: int,
) -> Verdict:
    """Measure ``pose`` once (see the module docstring).

    Parameters
    ----------
    stepper, moving
        The run's fixed spectra and moving cloud.
    fixed : open3d.geometry.PointCloud
        The fixed cloud with normals (:func:`o3d_spectral.refinement.icp.with_normals`).
    pose : ndarray, shape (4, 4)
        The polished pose, moving cloud to fixed cloud.
    others : list of ndarray (4, 4)
        The search's other hypotheses, as poses of the moving cloud.
    culls : bool
        The source is matched as the target's sensor would see it.
    readings : dict of str to CloudReading
        How each cloud (``"source"``, ``"target"``) was read, in its own frame.
    converged, max_iteration
        Whether the law met its criteria, and their iteration budget.

    Returns
    -------
    Verdict
    """
    fixed_points = FixedPoints(fixed)  # its trees serve every fit
    measured = measure(stepper, moving, fixed_points, pose, others, culls=culls)
    rival = ambiguity(stepper, moving, fixed_points, pose, measured, culls=culls)
    evidence = pose_evidence(
        moving.points, moving.point_normals, stepper.target_normal_points,
        stepper.target_normals, pose, stepper.voxel_size, fit=measured.fit,
        rival_fit=rival.fit, ambiguous=rival.ambiguous, rival_self_match=rival.self_match,
        two_views=stepper.viewpoint is not None and not culls, sensor=stepper.viewpoint,
        two_sided=moving.reading.two_sided, tree=stepper.normals_tree)
    probability = confidence(evidence)
    angle = rival.angle if rival.ambiguous else None
    warnings, notes = registration_messages(
        converged=converged, max_iteration=max_iteration, readings=readings,
        confidence=probability, ambiguity=angle,
        symmetric_rival=readings["source"].view is None and rival.symmetric,
        free_motions=evidence.free_motions)
    return Verdict(measured.fit, measured.rival_fit, angle,
                   rival.pose if rival.ambiguous else None, evidence, probability, warnings,
                   notes)
