"""What both registration calls share: their run's state, its start and its finish.

:func:`start` checks the arguments, centres the clouds on the target and prepares both
(:class:`o3d_spectral.SpectralStepper`, :class:`o3d_spectral.law.stepper.MovingCloud`);
:func:`finish` polishes a pose (:mod:`o3d_spectral.refinement.icp`), judges it once
(:mod:`o3d_spectral.evidence.verdict`: its fit, evidence, confidence, warnings and notes), measures
it as Open3D does, and fills the result in the caller's frame.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import open3d as o3d
from numpy.typing import ArrayLike, NDArray

from .common.checks import (
    check_instance,
    check_number,
    check_reach,
    check_transformation,
    check_voxel_size,
)
from .evidence.verdict import Verdict, verdict
from .io.cloud import CloudArrays, CloudReading, as_arrays, extent, to_legacy
from .io.density import read_at_voxels
from .io.units import check_same_units
from .law import centring
from .law.loop import Climb, climb
from .law.prepared import PreparedSource
from .law.prepared_target import PreparedTarget
from .law.stepper import MovingCloud, SpectralStepper
from .options import (
    CloudOption,
    RefinementOption,
    SpectralConvergenceCriteria,
    SpectralRegistrationOption,
)
from .refinement.constants import REFINEMENT_MARGIN
from .refinement.icp import near_pose, refine, with_normals
from .result import SpectralRegistrationResult
from .search.options import GlobalSearchOption
from .search.situation import Situation, situation

__all__ = ["Run", "check_settings", "start", "finish", "DEFAULT_REFINEMENT",
           "REFINEMENT_MARGIN"]

#: The default polish: point-to-plane ICP at 0.4 voxel after a 1-voxel pass where better.
DEFAULT_REFINEMENT = RefinementOption()


@dataclass
class Run:
    """What both calls share: the clouds as arrays, the fixed spectra, the moving cloud,
    the kind of problem, the settings and the clock."""

    source: CloudArrays
    target: CloudArrays
    stepper: SpectralStepper
    moving: MovingCloud
    init: NDArray[np.float64]
    criteria: SpectralConvergenceCriteria
    start: float
    offset: NDArray[np.float64] | None  # where the clouds were centred (centring module)
    situation: Situation
    #: Indices in the caller's clouds of the points read (io.density: a dense cloud's
    #: one per quarter-voxel cell), or None where every point is read.
    source_index: NDArray[np.int64] | None = None
    target_index: NDArray[np.int64] | None = None

    @property
    def fixed_normals(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The fixed cloud's down-sampled points and their normals, (N, 3) each."""
        return self.stepper.target_normal_points, self.stepper.target_normals

    def moving_pose(self, transformation: NDArray[np.float64]) -> NDArray[np.float64]:
        """A source-to-target ``transformation`` (4, 4) in the caller's frame as a pose of
        the moving cloud in the frame the run works in (centred, after ``init``)."""
        if self.offset is not None:
            transformation = centring.shifted(transformation, self.offset)
        return transformation @ np.linalg.inv(self.init)

    def climb(self, state: Climb, iterations: int) -> None:
        """The law on ``state`` for at most ``iterations``."""
        tolerance = self.criteria.tolerances(self.stepper.voxel_size)
        climb(self.stepper, self.moving, state, iterations, tolerance, self.init, self.start)


def check_settings(**settings: object) -> None:
    """Each setting is None or an instance of its o3d_spectral class; the distance a
    positive number of metres or None."""
    classes = {"option": SpectralRegistrationOption, "criteria": SpectralConvergenceCriteria,
               "cloud": CloudOption, "search": GlobalSearchOption,
               "refinement": RefinementOption}
    for name, value in settings.items():
        if name == "max_correspondence_distance":
            check_number(name, value, low=0.0, low_open=True, optional=True)
        else:
            check_instance(name, value, classes[name])


def start(
    source: object, target: object, voxel_size: float, init: ArrayLike,
    option: SpectralRegistrationOption | None, criteria: SpectralConvergenceCriteria | None,
    cloud: CloudOption | None, device: object | None = None,
) -> Run:
    """Check the arguments, compute the fixed spectra (their correlations on ``device``)
    and prepare the moving cloud."""
    start = time.perf_counter()
    voxel_size = check_voxel_size(voxel_size)  # type first, then value, by name
    init = check_transformation(init)
    ready = source if isinstance(source, PreparedSource) else None
    if ready is not None:
        ready.check(voxel_size, option, cloud)
        source = ready.arrays
    fixed = target if isinstance(target, PreparedTarget) else None
    if fixed is not None:
        fixed.check(voxel_size, option, cloud, device)
        target = fixed.arrays
    source, target = as_arrays(source, "source"), as_arrays(target, "target")  # once
    check_same_units(source.points, target.points)  # 50x apart: other units, or a scene to crop
    check_reach(init, source.points, target.points, voxel_size)
    # a dense cloud read one point per quarter-voxel cell, as prepare(_target) reads it
    (source, source_index), (target, target_index) = (read_at_voxels(c, voxel_size)
                                                      for c in (source, target))
    c, origin = centring.offset(target), None
    prepared = None if ready is None else ready.cloud
    if c is not None:  # far from the origin: register in a frame centred on the target
        source, target = centring.centred_arrays(source, c), centring.centred_arrays(target, c)
        cloud = centring.centred_option(cloud or CloudOption(), c)
        init, origin = centring.shifted(init, c), -c
        prepared = None if ready is None else ready.moved(c)
    stepper = (fixed.stepper if fixed is not None else
               SpectralStepper(target, voxel_size, option=option, cloud=cloud,
                               frame_origin=origin, device=device))
    moving = stepper.moving(source, "source", transformation=init, prepared=prepared)
    criteria = criteria or SpectralConvergenceCriteria()
    return Run(source, target, stepper, moving, init, criteria, start, c,
               situation(stepper, moving), source_index, target_index)


def finish(
    run: Run, result: SpectralRegistrationResult, best: Climb,
    transformation: NDArray[np.float64], refinement: RefinementOption | None,
    max_correspondence_distance: float | None,
) -> SpectralRegistrationResult:
    """Polish ``transformation`` (4, 4), judge it once
    (:func:`o3d_spectral.evidence.verdict.verdict`), measure it as Open3D does
    (``fitness``, ``inlier_rmse``, ``correspondence_set``), and fill ``result`` in the
    caller's frame."""
    source, target = to_legacy(run.source), to_legacy(run.target)
    fixed = with_normals(target, *run.fixed_normals)  # the polish's and the verdict's
    pose = _polished(run, source, fixed, transformation, refinement)
    readings = {"source": run.moving.reading.turned(run.init[:3, :3].T),  # source frame
                "target": run.stepper.target_reading}
    to_moving = np.linalg.inv(run.init)  # the moving cloud is the source posed by init
    judged = verdict(run.stepper, run.moving, fixed, pose @ to_moving,
                     [M @ to_moving for M, _ in result.hypotheses],
                     culls=run.situation.culls, readings=readings, converged=best.converged,
                     max_iteration=run.criteria.max_iteration)
    distance = (run.stepper.voxel_size if max_correspondence_distance is None
                else max_correspondence_distance)
    _open3d_measures(run, result, source, target, pose, distance)
    return _filled(run, result, best, pose, judged, readings, distance)


def _polished(
    run: Run, source: o3d.geometry.PointCloud, fixed: o3d.geometry.PointCloud,
    transformation: NDArray[np.float64], refinement: RefinementOption | None,
) -> NDArray[np.float64]:
    """``transformation`` polished where ``refinement`` is set (:func:`refined`), checked
    finite."""
    if refinement is not None:
        transformation = refined(run, source, fixed, transformation, refinement)
    if not np.all(np.isfinite(transformation)):  # never expected: guard the contract
        raise FloatingPointError("the registration produced a non-finite transformation")
    return transformation


def _open3d_measures(
    run: Run, result: SpectralRegistrationResult, source: o3d.geometry.PointCloud,
    target: o3d.geometry.PointCloud, pose: NDArray[np.float64], distance: float,
) -> None:
    """Open3D's ``evaluate_registration`` of ``pose`` on the target near it: ``fitness``,
    ``inlier_rmse`` and ``correspondence_set`` (indices in the caller's clouds) set in
    ``result``; left at 0 where no target point is within ``distance``."""
    near, indices = near_pose(target, run.source.points, pose, distance)
    if len(indices) == 0:
        return
    evaluation = o3d.pipelines.registration.evaluate_registration(source, near, distance, pose)
    pairs = np.asarray(evaluation.correspondence_set)
    pairs[:, 1] = indices[pairs[:, 1]]  # the whole target's
    for column, index in enumerate((run.source_index, run.target_index)):
        if index is not None:  # back to the caller's points
            pairs[:, column] = index[pairs[:, column]]
    result.fitness = evaluation.fitness
    result.inlier_rmse = evaluation.inlier_rmse
    result.correspondence_set = o3d.utility.Vector2iVector(pairs)


def _filled(
    run: Run, result: SpectralRegistrationResult, best: Climb, pose: NDArray[np.float64],
    judged: Verdict, readings: dict[str, CloudReading], distance: float,
) -> SpectralRegistrationResult:
    """``result`` filled with the climb, the polished ``pose`` and its verdict, everything
    moved to the caller's frame at once."""
    result.history, result.converged = best.history, best.converged
    result.num_iterations = len(best.history)
    result.source_reading, result.target_reading = readings["source"], readings["target"]
    result.fit, result.ambiguity = judged.fit, judged.ambiguity
    rival = judged.rival  # a pose of the moving cloud (the source posed by init)
    if rival is not None:  # source to target; a non-finite one (never seen) is not returned
        rival = rival @ run.init if np.all(np.isfinite(rival)) else None
    result.ambiguous_transformation = rival
    result.rival_fit = max(result.rival_fit, judged.rival_fit)  # the confirmation's too
    result.pose_evidence, result.confidence = judged.evidence, judged.confidence
    result.warnings, result.notes = judged.warnings, judged.notes
    result.transformation, result.free_motions = pose, judged.free_motions
    if run.situation.culls:
        result.target_viewpoint = run.stepper.viewpoint.copy()
    if run.offset is not None:  # back to the caller's frame
        result.transformation = centring.shifted(pose, -run.offset)
        if rival is not None:
            result.ambiguous_transformation = centring.shifted(rival, -run.offset)
        result.history = centring.uncentred_history(result.history, run.offset)
        result.hypotheses = [(centring.shifted(M, -run.offset), s) for M, s in result.hypotheses]
        result.free_motions = tuple(m.shifted(run.offset) for m in judged.free_motions)
        if result.target_viewpoint is not None:
            result.target_viewpoint += run.offset
    result.max_correspondence_distance = distance
    result.run_time = time.perf_counter() - run.start
    return result


def refined(
    run: Run, source: o3d.geometry.PointCloud, fixed: o3d.geometry.PointCloud,
    transformation: NDArray[np.float64], refinement: RefinementOption,
) -> NDArray[np.float64]:
    """:func:`o3d_spectral.refinement.icp.refine` against the target with normals (``fixed``)
    near the pose: the part of a scene within the source's size of it (the polish moves
    the source far less)."""
    margin = max(extent(run.source.points)[1], REFINEMENT_MARGIN * run.stepper.voxel_size)
    near, kept = near_pose(fixed, run.source.points, transformation, margin)
    if len(kept) == 0:  # nothing within reach: no ICP correspondence, nothing to polish
        return transformation
    return refine(source, near, run.stepper.voxel_size, transformation, refinement)
