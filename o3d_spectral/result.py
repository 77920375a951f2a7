"""What the registration calls return: Open3D's ``RegistrationResult`` and more."""

from __future__ import annotations

import numpy as np
import open3d as o3d
from numpy.typing import NDArray

from .evidence.free_motions import FreeMotion
from .evidence.pose import PoseEvidence
from .io.cloud import CloudReading
from .law.loop import IterationRecord

__all__ = ["SpectralRegistrationResult"]


class SpectralRegistrationResult(o3d.pipelines.registration.RegistrationResult):
    """Open3D's ``RegistrationResult`` with the spectral method's extra outputs.

    ``transformation``, ``fitness``, ``inlier_rmse`` and ``correspondence_set`` mean what
    they mean for Open3D's own methods: they come from
    ``open3d.pipelines.registration.evaluate_registration`` at
    :attr:`max_correspondence_distance`, measured on the points the call read: all of a
    cloud's, or, for a dense cloud (over 64 points per occupied voxel), the first point in
    each cell of a quarter voxel (:mod:`o3d_spectral.io.density`; every stage of the call
    reads the same points). ``fitness`` is the share of those source points with a target
    point within the distance; ``correspondence_set`` holds their indices in the caller's
    clouds.

    Attributes
    ----------
    converged : bool
        The convergence criteria were met before ``max_iteration``.
    num_iterations : int
    history : list of IterationRecord
        The law's iterations from ``init`` (local call), or those of the hypothesis
        climbed on to convergence (global call).
    run_time : float
        Seconds, from the call to the return (evaluation included).
    max_correspondence_distance : float
        Metres.
    translation_peak : float
        Phase-correlation peak height in [0, 1] at the returned pose before the
        refinement, a figure of the search.
    hypotheses : list of (ndarray (4, 4), float)
        Global call only: for each climbed hypothesis, its best-scoring iterate and its
        score (phase-correlation peak times EGI correlation), best first. The returned
        transformation is the first, refined.
    confidence : float
        The probability, in [0, 1], that the pose is right: within 5 degrees and 1 cm
        of the truth at the source's centroid, over the object's symmetries where it has
        some. A logistic model (:mod:`o3d_spectral.evidence.confidence`) of the pose's
        evidence (:attr:`pose_evidence`), calibrated on development registrations and
        checked on held-back ones (docs/errors.md); under 0.5 a warning says the pose may
        be wrong. Both calls.
    search_margin : float
        Global call only: the best hypothesis' score minus that of the best hypothesis
        ending in a distinct rotation (over 10 degrees away); for a confirmed result, its
        fit's lead over the best distinct alternative; 0 for the local call. A figure of
        the search.
    fit : float
        How well the returned pose fits, in [0, 1]: the share of the source's points (one
        per voxel) that the target's sensor would see there (all of them when the target
        is not a single view) lying within one voxel of the target after a short
        point-to-plane polish (:func:`o3d_spectral.evidence.fit.fit`). Unlike
        ``fitness`` it does not count the back of a model, which a view cannot hold, as
        missed (:mod:`o3d_spectral.evidence.verification`). One of the confidence's inputs.
    rival_fit : float
        Global call only: the best ``fit`` of a hypothesis that ends over 10 degrees from
        the returned pose (0 when there is none, and for the local call).
    ambiguity : float or None
        Where a distinct pose fits as well as the returned one (within
        :data:`o3d_spectral.evidence.verification.AMBIGUITY_MARGIN`): the angle between them,
        degrees (a symmetric object, or one the target shows too little of to tell);
        None otherwise. A warning says so; a note where the rival is the returned pose
        turned by a symmetry of the whole source (a model, not a view): both are right.
    ambiguous_transformation : ndarray, shape (4, 4), or None
        Where :attr:`ambiguity` is set, that distinct pose (source to target, as
        ``transformation``; polished where it was): the other answer the data allow, to
        check against what the object's symmetry or the scene says; None otherwise.
    free_motions : tuple of FreeMotion
        The motions of the source that leave its fit unchanged farther than a pose's
        tolerance (:mod:`o3d_spectral.evidence.free_motions`): a turn about an axis or a slide
        along one, how far each way (degrees or metres), and whether it is a symmetry of
        the source (the pose is right up to it; of a single view's surface, where the
        object shares it) or a motion the data do not fix. In the
        target's frame; empty for most poses. A symmetry is a note (:attr:`notes`), any
        other a warning; the confidence does not count them.
    pose_evidence : PoseEvidence or None
        What the confidence was computed from (:class:`o3d_spectral.evidence.pose.PoseEvidence`):
        the fits, the plane distance, the normals' agreement, the free-space violation.
    source_reading, target_reading : CloudReading
        How each cloud was read: where its normals came from (given, re-oriented,
        estimated), the rule that oriented them, and the direction towards its sensor
        when its normals say it is a single view (:class:`o3d_spectral.io.cloud.CloudReading`).
    target_viewpoint : ndarray, shape (3,), or None
        Where the target's sensor was taken to be (metres) when the source was matched
        as that sensor would see it (back faces culled); None when matched whole.
    warnings : list of str
        What was logged as a warning during the call: what the caller should check (the
        pose may be wrong, an input was not as expected; :mod:`o3d_spectral.evidence.diagnostics`).
    notes : list of str
        What was logged as a note (``logging.INFO``): how the data were read, a symmetric
        twin of the pose, its free motions; nothing to check.
    confirmed : bool
        Global call only: the search's best placed hypothesis was confirmed by its fit
        (:mod:`o3d_spectral.search.confirmation`) and the climbs were skipped; ``hypotheses``
        then holds that pose with its fit, ``search_margin`` its fit's lead over the best
        distinct alternative, and ``history`` is empty.
    stage_times : dict of str to float
        Seconds spent in each stage of the call, in the order they ran
        (:mod:`o3d_spectral.common.stages`): ``prepare``, ``candidates``, ``confirm``,
        ``sweep``, ``climbs``, ``ascent``, ``polish`` for the global call (those it ran);
        ``prepare``, ``law``, ``polish`` for the local one.
    """

    def __init__(self) -> None:
        super().__init__()
        self.converged = False
        self.num_iterations = 0
        self.history: list[IterationRecord] = []
        self.run_time = 0.0
        self.max_correspondence_distance = 0.0
        self.translation_peak = 0.0
        self.hypotheses: list[tuple[NDArray[np.float64], float]] = []
        self.confidence = 0.0
        self.search_margin = 0.0
        self.fit = 0.0
        self.rival_fit = 0.0
        self.ambiguity: float | None = None
        self.ambiguous_transformation: NDArray[np.float64] | None = None
        self.pose_evidence: PoseEvidence | None = None
        self.free_motions: tuple[FreeMotion, ...] = ()
        self.source_reading = CloudReading()
        self.target_reading = CloudReading()
        self.target_viewpoint: NDArray[np.float64] | None = None
        self.warnings: list[str] = []
        self.notes: list[str] = []
        self.confirmed = False
        self.stage_times: dict[str, float] = {}

    def __repr__(self) -> str:
        return (
            f"SpectralRegistrationResult with fitness={self.fitness:e}, "
            f"inlier_rmse={self.inlier_rmse:e}, converged={self.converged}, "
            f"num_iterations={self.num_iterations}, run_time={self.run_time:.3f} s"
        )
