"""Other opinions on a doubtful pose: where the global search's result may be wrong (its
calibrated confidence under one half), other poses are polished and measured as it was,
and the most confident result is returned.

- :func:`turn_opinion`: the pose turned about the axis its inliers hold least
  (:mod:`o3d_spectral.search.turns`: a mug's body fits at every turn about its axis);
- :func:`second_opinion`: the search's other climbs, climbed on.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .common.parallel import thread_map
from .evidence.fit import fit
from .evidence.pose import Motion, weakest_motion
from .evidence.poses import distinct
from .law.loop import Climb
from .options import RefinementOption
from .result import SpectralRegistrationResult
from .run import Run, finish
from .search import GlobalSearch
from .search.turns import TURN_FINISHES, holds_every_motion, turn_axis, turned

__all__ = ["second_opinion", "turn_opinion"]


def second_opinion(
    run: Run, result: SpectralRegistrationResult,
    climbed: list[tuple[NDArray[np.float64], float]], count: int,
    refinement: RefinementOption | None, max_correspondence_distance: float | None,
) -> SpectralRegistrationResult:
    """``result``, or the most confident of the climbed poses distinct from it.

    Where the returned pose may be wrong (its calibrated confidence is under one half),
    the search's other climbs may hold the right one: up to ``count`` of ``climbed``
    (the climbs' best iterates, best first, 4x4 in the run's frame with their scores),
    distinct from the returned pose and from one another, are each climbed on by the law
    to convergence, polished and measured as the returned pose was
    (:func:`o3d_spectral.run.finish`); the result of the highest confidence is kept, the
    returned one where none is higher.
    """
    to_moving = np.linalg.inv(run.init)
    seen = [run.moving_pose(result.transformation)]
    kept = result
    for matrix, _ in climbed:
        if len(seen) > count:  # the returned pose and ``count`` others
            break
        pose = matrix @ to_moving
        if not all(distinct(pose, other) for other in seen):
            continue
        seen.append(pose)
        state = Climb.at(pose, run.moving.centroid)
        run.climb(state, run.criteria.max_iteration)
        other = _measured(run, result, climbed, state, state.matrix(), refinement,
                          max_correspondence_distance)
        other.translation_peak = state.history[-1].translation_peak
        if other.confidence > kept.confidence:
            kept = other
    return kept


def turn_opinion(
    run: Run, finder: GlobalSearch, result: SpectralRegistrationResult,
    climbed: list[tuple[NDArray[np.float64], float]], count: int,
    refinement: RefinementOption | None, max_correspondence_distance: float | None,
) -> SpectralRegistrationResult:
    """``result``, or the most confident of its turns about the axis its inliers hold
    least (:mod:`o3d_spectral.search.turns`).

    Where that motion is a turn the inliers barely resist, the returned pose is turned
    about its axis by each multiple of ``360 / count`` degrees, each turn polished and
    measured briefly (:func:`o3d_spectral.evidence.fit.fit`). Of the turns whose
    inliers then hold every motion (:func:`o3d_spectral.search.turns.holds_every_motion`), the
    :data:`TURN_FINISHES` best fitting distinct ones are polished and measured as the
    returned pose was (:func:`o3d_spectral.run.finish`); the most confident result that
    still holds every motion is kept, the returned one where none is more confident.
    ``climbed``: the search's hypotheses in the run's frame, kept in every result.
    """
    pose = run.moving_pose(result.transformation)
    axis = turn_axis(_weakest_motion(run, pose))
    if axis is None:
        return result
    stepper = run.stepper
    fits = thread_map(lambda start: fit(stepper, run.moving, finder.fixed, start),
                      turned(pose, axis, count), finder.option.workers)
    kept, seen = result, [pose]
    for other_fit in sorted(fits, key=lambda f: -f.share):
        if len(seen) > TURN_FINISHES:
            break
        if not all(distinct(other_fit.pose, other) for other in seen):
            continue
        motion = _weakest_motion(run, other_fit.pose)
        if motion is not None and not holds_every_motion(motion.share):
            continue
        seen.append(other_fit.pose)
        other = _measured(run, result, climbed, Climb.at(other_fit.pose, run.moving.centroid),
                          other_fit.pose, refinement, max_correspondence_distance)
        other.confirmed = result.confirmed
        if other.confidence > kept.confidence and holds_every_motion(
                other.pose_evidence.motion_support):
            kept = other
    return kept


def _weakest_motion(run: Run, pose: NDArray[np.float64]) -> Motion | None:
    """The motion the inliers of the moving cloud at ``pose`` (4, 4, the run's frame)
    resist least (:func:`o3d_spectral.evidence.pose.weakest_motion`)."""
    stepper = run.stepper
    return weakest_motion(run.moving.points, run.moving.point_normals, pose,
                          stepper.voxel_size, stepper.normals_tree, sensor=stepper.viewpoint,
                          two_sided=run.moving.reading.two_sided)


def _measured(
    run: Run, result: SpectralRegistrationResult,
    climbed: list[tuple[NDArray[np.float64], float]], state: Climb, pose: NDArray[np.float64],
    refinement: RefinementOption | None, max_correspondence_distance: float | None,
) -> SpectralRegistrationResult:
    """A new result for ``pose`` (4, 4, the run's frame, reached by ``state``), polished
    and measured as ``result`` was (:func:`o3d_spectral.run.finish`), with ``climbed`` as
    its hypotheses and ``result``'s search margin."""
    other = SpectralRegistrationResult()
    other.hypotheses, other.search_margin = list(climbed), result.search_margin
    return finish(run, other, state, pose @ run.init, refinement, max_correspondence_distance)
