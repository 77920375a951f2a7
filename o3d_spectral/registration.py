"""``registration_spectral``: the paper's method as an Open3D registration call."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import open3d as o3d
from numpy.typing import ArrayLike, NDArray

from . import so3
from .cloud import as_arrays, point_to_plane_icp, to_legacy
from .options import SpectralConvergenceCriteria, SpectralRegistrationOption
from .stepper import MovingCloud, SpectralStepper

__all__ = ["IterationRecord", "SpectralRegistrationResult", "registration_spectral"]

#: Rotations further apart than this (radians) are distinct hypotheses (confidence).
DISTINCT_ANGLE = np.deg2rad(10.0)
#: Voxels added to the moving cloud's radius for the ball of a focused EGI, and the
#: distance (voxels) from a hypothesis' points of the normals its climb matches.
FOCUS_MARGIN = 2.0

#: ``option.refinement``'s correspondence distance, voxels (Open3D's tutorial: 0.4).
REFINEMENT_DISTANCE = 0.4


@dataclass(frozen=True)
class IterationRecord:
    """One iteration of the control law (the data of the paper's Fig. 2).

    Attributes
    ----------
    iteration : int
    transformation : ndarray, shape (4, 4)
        Source-to-target estimate at the start of the iteration (``init`` included).
    rotation : ndarray, shape (3, 3)
        The law's ``R`` at the start of the iteration (about the source's centroid).
    translation : ndarray, shape (3,)
        The law's ``T`` at the start of the iteration, metres.
    cost_translation, cost_rotation : float
        ``J_t``, ``J_r`` at that pose.
    translation_gradient_norm : float
        ``||grad_glob T||``, metres.
    rotation_gradient_norm : float
        Norm of the rotation step, radians (the paper's ``||grad C_r||`` over the
        correlation's curvature).
    correlation : float
        ``C_r(R)``.
    translation_peak : float
        Phase-correlation peak height in [0, 1].
    time : float
        Seconds since the registration started, at the end of the iteration.
    centre : ndarray, shape (3,)
        Where the phase correlation put the source's centroid at this iteration
        (metres, target frame, after ``init``).
    """

    iteration: int
    transformation: NDArray[np.float64]
    rotation: NDArray[np.float64]
    translation: NDArray[np.float64]
    cost_translation: float
    cost_rotation: float
    translation_gradient_norm: float
    rotation_gradient_norm: float
    correlation: float
    translation_peak: float
    time: float
    centre: NDArray[np.float64]


class SpectralRegistrationResult(o3d.pipelines.registration.RegistrationResult):
    """Open3D's ``RegistrationResult`` with the spectral method's extra outputs.

    ``transformation``, ``fitness``, ``inlier_rmse`` and ``correspondence_set`` mean what
    they mean for Open3D's own methods: they come from
    ``open3d.pipelines.registration.evaluate_registration`` at
    :attr:`max_correspondence_distance`.

    Attributes
    ----------
    converged : bool
        The convergence criteria were met before ``max_iteration``.
    num_iterations : int
    history : list of IterationRecord
        The law's iterations from ``init`` (local search), or those of the hypothesis
        climbed on to convergence (global search).
    run_time : float
        Seconds, from the call to the return (evaluation included).
    max_correspondence_distance : float
        Metres.
    translation_peak : float
        Phase-correlation peak height in [0, 1] at the returned pose (before the
        refinement; after it with ``option.rank_refined``), a confidence figure.
    hypotheses : list of (ndarray (4, 4), float)
        Global search only: for each of the ``option.climbs`` hypotheses that were
        climbed, its best-scoring iterate and its score (``option.hypothesis_score``
        times the EGI correlation), best first; with ``option.rank_refined``, the
        iterate refined and scored again there. The returned transformation is the
        first, refined.
    confidence : float
        Global search only: the best score minus that of the best hypothesis ending in a
        distinct rotation (over 10 degrees away); 0 when local.
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

    def __repr__(self) -> str:
        return (
            f"SpectralRegistrationResult with fitness={self.fitness:e}, "
            f"inlier_rmse={self.inlier_rmse:e}, converged={self.converged}, "
            f"num_iterations={self.num_iterations}, run_time={self.run_time:.3f} s"
        )


@dataclass
class _Pose:
    """``x -> R (x - c) + c + T`` and its 4x4 form."""

    pivot: NDArray[np.float64]
    R: NDArray[np.float64] = field(default_factory=lambda: np.eye(3))
    T: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))

    def matrix(self) -> NDArray[np.float64]:
        out = np.eye(4)
        out[:3, :3] = self.R
        out[:3, 3] = self.pivot + self.T - self.R @ self.pivot
        return out


def _pose_score(
    stepper: SpectralStepper,
    moving: MovingCloud,
    rotation: NDArray[np.float64],
    centre: NDArray[np.float64],
    peak: float,
    correlation: float,
) -> float:
    """Score of a pose of the moving cloud (turned by ``rotation``, centroid at ``centre``,
    metres): ``option.hypothesis_score`` there (``peak``: its phase-correlation peak)
    times its EGI correlation ``4 pi C_r`` (``correlation``: ``C_r``)."""
    return stepper.score(moving, rotation, centre, peak) * 4.0 * np.pi * correlation


@dataclass
class _Climb:
    """One run of the control law: its pose, smoothing level, history, where the last
    phase correlation put the moving cloud's centroid (None before the first), the
    stepper it climbs against when not the registration's own (a focused EGI), and the
    scores of its iterates computed so far (:meth:`best_iterate`)."""

    pose: _Pose
    level: int = 0
    history: list[IterationRecord] = field(default_factory=list)
    converged: bool = False
    predicted: NDArray[np.float64] | None = None
    stepper: SpectralStepper | None = None
    scores: list[float] = field(default_factory=list)

    def best_iterate(
        self, stepper: SpectralStepper, moving: MovingCloud
    ) -> tuple[float, _Pose, IterationRecord]:
        """The iterate of this climb that scores best (the first of equals), with its
        pose: its rotation, and its centroid where its phase correlation put it.

        An iterate's score is ``option.hypothesis_score`` at its pose times its EGI
        correlation ``4 pi C_r`` (1 for identical EGIs). The law ascends ``C_r`` alone
        on EGIs that part of either cloud is missing from; the score also weighs where
        the voxels match, and on partial views it can fall as the law climbs away from a
        pose it started at.
        """
        for record in self.history[len(self.scores) :]:
            self.scores.append(_pose_score(
                stepper, moving, record.rotation, record.centre, record.translation_peak,
                record.correlation,
            ))
        k = int(np.argmax(self.scores))
        record = self.history[k]
        pose = _Pose(moving.centroid, record.rotation, record.centre - moving.centroid)
        return self.scores[k], pose, record


def _climb(
    stepper: SpectralStepper,
    moving: MovingCloud,
    climb: _Climb,
    iterations: int,
    tolerance: tuple[float, float],
    init: NDArray[np.float64],
    start: float,
) -> None:
    """Apply the control law (eq. control_law) up to ``iterations`` times, in place."""
    pose = climb.pose
    for _ in range(iterations):
        if climb.converged:
            return
        evaluation = stepper.evaluate(
            moving, pose.R, pose.T, level=climb.level, around=climb.predicted
        )
        climb.predicted = moving.centroid + pose.T + evaluation.translation
        t_norm = float(np.linalg.norm(evaluation.translation))
        r_norm = float(np.linalg.norm(evaluation.rotation))
        climb.history.append(
            IterationRecord(
                iteration=len(climb.history),
                transformation=pose.matrix() @ init,
                rotation=pose.R.copy(),
                translation=pose.T.copy(),
                cost_translation=evaluation.cost_translation,
                cost_rotation=evaluation.cost_rotation,
                translation_gradient_norm=t_norm,
                rotation_gradient_norm=r_norm,
                correlation=evaluation.correlation,
                translation_peak=evaluation.translation_peak,
                time=time.perf_counter() - start,
                centre=climb.predicted.copy(),
            )
        )
        level = stepper.next_level(climb.level, evaluation)
        if level == climb.level == stepper.levels - 1 and (
            t_norm < tolerance[0] and r_norm < tolerance[1]
        ):
            climb.converged = True
            return
        climb.level = level
        delta_rotation, delta_translation = stepper.increments(evaluation)
        pose.T = pose.T + delta_translation
        pose.R = so3.project_to_rotation(pose.R @ delta_rotation)


def _confidence(ranked: list[tuple[float, NDArray[np.float64]]]) -> float:
    """Best score minus the best score of a transformation over ``DISTINCT_ANGLE`` away
    (in rotation) from the best; the best score when every one is near it. ``ranked``:
    (score, 4x4 transformation), best first."""
    best_score, best = ranked[0]
    for score, other in ranked[1:]:
        if so3.rotation_angle(other[:3, :3].T @ best[:3, :3]) > DISTINCT_ANGLE:
            return best_score - score
    return best_score


def _rescored(
    stepper: SpectralStepper, moving: MovingCloud, transformation: NDArray[np.float64],
    init: NDArray[np.float64],
) -> tuple[float, float]:
    """Score (:func:`_pose_score`) of a source-to-target ``transformation`` (4, 4), and
    its phase-correlation peak: the moving cloud (the source moved by ``init``) at that
    pose, its translation searched near there."""
    pose = transformation @ np.linalg.inv(init)
    R, centre = pose[:3, :3], pose[:3, :3] @ moving.centroid + pose[:3, 3]
    e = stepper.evaluate(moving, R, centre - moving.centroid, around=centre)
    peak = e.translation_peak
    return _pose_score(stepper, moving, R, centre, peak, e.correlation), peak


def _hypotheses(
    stepper: SpectralStepper,
    moving: MovingCloud,
    around: NDArray[np.float64] | None = None,
    rotations: list[NDArray[np.float64]] | None = None,
) -> list[tuple[float, _Climb]]:
    """A climb from each of :meth:`SpectralStepper.hypotheses` (placed near ``around``
    when given; ``rotations`` instead of the correlation's peaks when given), with its
    score."""
    return [
        (h.score, _Climb(_Pose(moving.centroid, h.rotation, h.centre - moving.centroid),
                         predicted=h.centre))
        for h in stepper.hypotheses(moving, around=around, rotations=rotations)
    ]


def _candidates(
    stepper: SpectralStepper, moving: MovingCloud, around: NDArray[np.float64] | None = None
) -> list[tuple[float, _Climb]]:
    """A climb from each of the best candidate rotations, with its score, best first.

    The candidates are the rotation correlation's ``option.hypotheses`` peaks and
    ``option.sampled_rotations`` rotations spread over SO(3). Each is placed by phase
    correlation on a grid ``option.placement_coarsening`` times coarser (near
    ``around``, metres, when given; anywhere in the fixed cloud otherwise); the
    ``option.placed_again`` with the highest peaks are placed again, and scored, on the
    full grid near there.
    """
    option = stepper.option
    if option.placement_coarsening == 1 and not option.sampled_rotations:
        return _hypotheses(stepper, moving, around=around)
    coarse = stepper.coarsened(option.placement_coarsening)
    rough = coarse.hypotheses(moving, around=around)
    if option.sampled_rotations:
        samples = so3.uniform_samples(option.sampled_rotations)
        rough += coarse.hypotheses(moving, around=around, rotations=samples)
    rough = sorted(rough, key=lambda h: -h.translation_peak)[: option.placed_again]
    return _by_score([
        scored
        for h in rough
        for scored in _hypotheses(stepper, moving, around=h.centre, rotations=[h.rotation])
    ])


def _places(ranked: list[tuple[float, _Climb]], separation: float) -> list[NDArray[np.float64]]:
    """Where the ranked climbs put the moving cloud's centroid (metres), best first,
    each over ``separation`` (metres) from the ones before."""
    places: list[NDArray[np.float64]] = []
    for _, climb in ranked:
        if all(np.linalg.norm(climb.predicted - p) > separation for p in places):
            places.append(climb.predicted)
    return places


def _by_score(scored: list[tuple]) -> list[tuple]:
    """``scored`` (tuples, score first) sorted best first (stable)."""
    return sorted(scored, key=lambda item: -item[0])


def _global_search(
    stepper: SpectralStepper,
    moving: MovingCloud,
    criteria: SpectralConvergenceCriteria,
    *args: object,
) -> list[tuple[float, _Climb]]:
    """Hypotheses from the whole SO(3), climbed a little, best first.

    Every candidate rotation is located by phase correlation and scored
    (:func:`_candidates`). With ``option.egi_focus``, in a fixed cloud larger than the
    moving one, the fixed EGI is then focused on a ball about each of the
    ``option.focus_places`` best distinct places the candidates put the moving cloud,
    each such correlation's candidates are added, and each climbed hypothesis matches
    the normals near its own points (:meth:`SpectralStepper.focused`). The
    ``option.climbs`` best are climbed ``option.hypothesis_iterations`` times and ranked
    again, by their best iterate (:meth:`_Climb.best_iterate`).
    """
    option = stepper.option
    ranked = _candidates(stepper, moving)  # best first
    focus = False
    if option.egi_focus:
        radius = moving.radius + FOCUS_MARGIN * stepper.voxel_size
        for located in _places(ranked, moving.radius)[: option.focus_places]:
            ball = stepper.focused(located[None, :], radius)
            if ball is stepper:  # the fixed cloud is about the moving one's size
                break
            focus = True
            ranked = ranked + _candidates(ball, moving, around=located)
        ranked = _by_score(ranked)
    climbs = [climb for _, climb in ranked[: option.climbs]]
    budget = min(option.hypothesis_iterations, criteria.max_iteration)
    scored = []
    for climb in climbs:
        if focus:  # the scene's normals near this hypothesis' own points, kept for its climb
            near = stepper.visible_points(moving, climb.pose.R, climb.pose.T)
            climb.stepper = stepper.focused(near, FOCUS_MARGIN * stepper.voxel_size)
        _climb(climb.stepper or stepper, moving, climb, budget, *args)
        scored.append((climb.best_iterate(stepper, moving)[0], climb))
    return _by_score(scored)


def _check_transformation(init: ArrayLike) -> NDArray[np.float64]:
    M = np.asarray(init, dtype=np.float64)
    if M.shape != (4, 4):
        raise ValueError(f"init must be a 4x4 matrix, got shape {M.shape}")
    rigid = so3.is_rotation(M[:3, :3]) and np.allclose(M[3], [0.0, 0.0, 0.0, 1.0])
    if not (rigid and np.all(np.isfinite(M))):
        raise ValueError("init must be a finite rigid transformation (rotation + translation)")
    return M


def point_to_plane_refinement(
    source: o3d.geometry.PointCloud,
    target: o3d.geometry.PointCloud,
    voxel_size: float,
    init: ArrayLike,
) -> NDArray[np.float64]:
    """Open3D's point-to-plane ICP from ``init`` (4, 4), correspondences up to
    ``0.4 * voxel_size`` (metres): the refinement of Open3D's global-registration
    tutorial, used by ``option.refinement`` and by the harness' FPFH baselines.

    ``target`` must have normals. Deterministic (:func:`o3d_spectral.cloud.point_to_plane_icp`).
    """
    return point_to_plane_icp(source, target, REFINEMENT_DISTANCE * voxel_size, init)


def _widened_refinement(
    source: o3d.geometry.PointCloud,
    target: o3d.geometry.PointCloud,
    voxel_size: float,
    init: NDArray[np.float64],
    wide: float | None,
) -> NDArray[np.float64]:
    """:func:`point_to_plane_refinement` from ``init``, and, with ``wide`` (voxels), the
    same after a first ICP with correspondences up to ``wide`` voxels; the one that fits
    better (Open3D's fitness at the refinement's 0.4 voxel, the first of equals).

    ``init`` itself when the kept result has at most half as many inliers at 0.4 voxel
    as ``init``: from a wrong pose with few correspondences on a thin or flat part, the
    ICP's normal equations are nearly singular and it can leave the surface altogether
    (a scissors view sent 90 m away), which no refinement should do.
    """

    def fitness(transformation: NDArray[np.float64]) -> float:
        return o3d.pipelines.registration.evaluate_registration(
            source, target, REFINEMENT_DISTANCE * voxel_size, transformation
        ).fitness

    refined = point_to_plane_refinement(source, target, voxel_size, init)
    kept = fitness(refined)
    if wide is not None:
        widened = point_to_plane_refinement(
            source, target, voxel_size, point_to_plane_icp(source, target, wide * voxel_size, init)
        )
        if (fit := fitness(widened)) > kept:
            refined, kept = widened, fit
    return init if kept <= 0.5 * fitness(init) else refined


def _with_normals(
    target: o3d.geometry.PointCloud, stepper: SpectralStepper
) -> o3d.geometry.PointCloud:
    """``target``, or, when it has no normals, the down-sampled points and normals the
    stepper prepared."""
    if target.has_normals():
        return target
    fixed = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(stepper.target_normal_points))
    fixed.normals = o3d.utility.Vector3dVector(stepper.target_normals)
    return fixed


def registration_spectral(
    source: object,
    target: object,
    voxel_size: float,
    init: ArrayLike = np.eye(4),  # noqa: B008  (read-only, as in Open3D)
    option: SpectralRegistrationOption | None = None,
    criteria: SpectralConvergenceCriteria | None = None,
) -> SpectralRegistrationResult:
    """Align ``source`` to ``target`` with the spectral control law (no correspondences).

    Translation comes from 3D phase correlation of voxel grids, rotation from a gradient
    ascent of the correlation of Extended Gaussian Images (surface-normal histograms) on
    SO(3), both updated at once each iteration until both corrections are small
    (Adjigble et al., "Direct 3D visual servoing in the spectral domain", 2022).

    Parameters
    ----------
    source, target : open3d.geometry.PointCloud, open3d.t.geometry.PointCloud or ndarray
        Clouds in metres; numpy arrays of shape (N, 3), or (N, 6) with normals in the last
        three columns. Neither is modified. Normals are used when present; otherwise they
        are estimated (PCA, radius ``option.normal_radius``) and oriented towards
        ``option.camera_location``, or towards the origin when the cloud is a depth map
        seen from the origin (a scan in its sensor's frame), or outward (a model).
        Given normals must be consistently oriented (outward for a model, towards the
        sensor for a scan).
    voxel_size : float
        Voxel edge, metres (the paper uses 0.008). Both clouds are down-sampled to it.
    init : array_like, shape (4, 4), optional
        Initial source-to-target transformation (applied to the source first).
    option : SpectralRegistrationOption, optional
        Representation and gains.
    criteria : SpectralConvergenceCriteria, optional
        Stopping rule.

    Returns
    -------
    SpectralRegistrationResult
        ``transformation`` maps source points onto the target (4x4, float64, rigid).

    Raises
    ------
    ValueError
        For an empty cloud, too few points at this voxel size, NaN or infinite
        coordinates, a voxel size that is not positive or would need more than
        ``option.max_grid_memory``, a non-rigid ``init`` or an array of the wrong shape.
    TypeError
        For an unsupported cloud type.

    Notes
    -----
    By default the rotation search is local (the paper's gradient ascent from ``init``):
    it reliably corrects rotations up to a few tens of degrees. With
    ``option.rotation_search="global"`` it starts from the peaks of the rotation
    correlation over all of SO(3) instead, climbs the best few, and returns the iterate
    of those climbs that scores best. The translation is always found globally.
    The pose is then polished by a point-to-plane ICP with correspondences within
    0.4 voxel, or by the same after a wider first pass where that fits better, and
    kept only if it has not slid off the surface (``option.refinement``,
    ``option.refinement_wide_distance``; None keeps the law's pose, correspondence-free);
    with ``option.rank_refined`` the global search polishes each climb's best iterate,
    scores it again there and returns the best.

    Examples
    --------
    >>> import open3d as o3d, o3d_spectral
    >>> result = o3d_spectral.registration_spectral(source, target, 0.008)  # doctest: +SKIP
    >>> source.transform(result.transformation)  # doctest: +SKIP
    """
    start = time.perf_counter()
    option = option or SpectralRegistrationOption()
    criteria = criteria or SpectralConvergenceCriteria()
    init = _check_transformation(init)
    source, target = as_arrays(source, "source"), as_arrays(target, "target")  # once
    stepper = SpectralStepper(target, voxel_size, option=option)
    moving = stepper.moving(source, "source", transformation=init)

    tolerance = (criteria.translation_tolerance or 0.02 * voxel_size, criteria.rotation_tolerance)
    result = SpectralRegistrationResult()
    climbs: list[_Climb] = []
    if option.rotation_search == "local":
        best = _Climb(_Pose(moving.centroid, np.eye(3)))
    else:
        ranked = _global_search(stepper, moving, criteria, tolerance, init, start)
        climbs = [climb for _, climb in ranked]
        best = climbs[0]
    left = criteria.max_iteration - len(best.history)
    _climb(best.stepper or stepper, moving, best, left, tolerance, init, start)
    result.history, result.converged = best.history, best.converged
    result.num_iterations = len(best.history)
    source_legacy, target_legacy = to_legacy(source), to_legacy(target)  # once, for both

    def refine(transformation: NDArray[np.float64]) -> NDArray[np.float64]:
        if option.refinement != "point_to_plane":
            return transformation
        return _widened_refinement(
            source_legacy, _with_normals(target_legacy, stepper), voxel_size, transformation,
            option.refinement_wide_distance,
        )

    if climbs:  # the best iterate of each climb (refined and scored again: rank_refined)
        ranked = []
        for climb in climbs:
            score, pose, record = climb.best_iterate(stepper, moving)
            transformation, peak = pose.matrix() @ init, record.translation_peak
            if option.rank_refined and option.refinement is not None:
                transformation = refine(transformation)
                score, peak = _rescored(climb.stepper or stepper, moving, transformation, init)
            ranked.append((score, transformation, peak))
        ranked = _by_score(ranked)
        result.hypotheses = [(M, score) for score, M, _ in ranked]
        result.confidence = _confidence([(score, M) for score, M, _ in ranked])
        _, transformation, result.translation_peak = ranked[0]
        if not option.rank_refined:
            transformation = refine(transformation)
    else:
        transformation = refine(best.pose.matrix() @ init)
        result.translation_peak = best.history[-1].translation_peak
    if not np.all(np.isfinite(transformation)):  # never expected: guard the contract
        raise FloatingPointError("the registration produced a non-finite transformation")
    distance = option.max_correspondence_distance or voxel_size
    evaluation = o3d.pipelines.registration.evaluate_registration(
        source_legacy, target_legacy, distance, transformation
    )
    result.transformation = transformation
    result.fitness = evaluation.fitness
    result.inlier_rmse = evaluation.inlier_rmse
    result.correspondence_set = evaluation.correspondence_set
    result.max_correspondence_distance = distance
    result.run_time = time.perf_counter() - start
    return result
