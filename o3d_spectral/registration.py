"""The public calls, shaped like Open3D's registration functions.

- :func:`registration_spectral`: the paper's control law from ``init`` (a local rotation
  search, the translation found globally), like ``registration_icp``;
- :func:`registration_spectral_global`: the rotation searched over all of SO(3) first
  (:class:`o3d_spectral.search.GlobalSearch`), like
  ``registration_fgr_based_on_feature_matching``.

Both prepare the fixed cloud's spectra (:class:`o3d_spectral.SpectralStepper`) and the
moving cloud, run the law (:mod:`o3d_spectral.law.loop`), polish the pose
(:mod:`o3d_spectral.refinement.icp`) and measure it as Open3D does (:mod:`o3d_spectral.run`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .common.stages import StageClock
from .evidence.diagnostics import may_be_wrong
from .evidence.poses import confidence
from .law.loop import Climb
from .opinions import second_opinion, turn_opinion
from .options import (
    CloudOption,
    RefinementOption,
    SpectralConvergenceCriteria,
    SpectralRegistrationOption,
)
from .result import SpectralRegistrationResult
from .run import DEFAULT_REFINEMENT, Run, check_settings, finish, start
from .search import GlobalSearch, Ranking
from .search.confirmation import Confirmation
from .search.options import GlobalSearchOption

__all__ = ["SpectralRegistrationResult", "registration_spectral", "registration_spectral_global",
           "Searched", "searched", "placed_result"]


_COMMON_PARAMETERS = """source, target : PointCloud, tensor PointCloud or ndarray
        Clouds in metres (``open3d.geometry.PointCloud``, ``open3d.t.geometry.PointCloud``);
        numpy arrays of shape (N, 3), or (N, 6) with normals in the last three columns.
        Neither is modified. ``source`` may also be a :class:`PreparedSource`
        (:func:`o3d_spectral.prepare`), to register one model to many targets, and
        ``target`` a :class:`PreparedTarget` (:func:`o3d_spectral.prepare_target`), to
        register many sources to one target. Normals are
        used when present (oriented again, with a warning, when neighbours' point to
        opposite sides: an estimate with no orientation step); otherwise estimated (PCA,
        radius ``cloud.normal_radius``). Signs are chosen towards ``cloud.camera_location``,
        or towards the origin for a depth map seen from it (a scan in its sensor's frame),
        or outward along the surface (a model, or a view in another frame). A cloud whose
        normals lie in one hemisphere is a single view (``result.source_reading.view``): a
        model is matched against a view as its sensor would see it; two views are matched
        whole.
    voxel_size : float
        Voxel edge, metres (the paper uses 0.008). Both clouds are down-sampled to it."""


def registration_spectral(
    source: object,
    target: object,
    voxel_size: float,
    init: ArrayLike = np.eye(4),  # noqa: B008  (read-only, as in Open3D)
    option: SpectralRegistrationOption | None = None,
    criteria: SpectralConvergenceCriteria | None = None,
    *,
    cloud: CloudOption | None = None,
    refinement: RefinementOption | None = DEFAULT_REFINEMENT,
    max_correspondence_distance: float | None = None,
) -> SpectralRegistrationResult:
    """Align ``source`` to ``target`` with the spectral control law from ``init``.

    Translation comes from 3D phase correlation of voxel grids (global: any offset),
    rotation from a gradient ascent of the correlation of Extended Gaussian Images
    (surface-normal histograms) on SO(3) from ``init`` (local: reliable up to a few tens
    of degrees), both updated at once each iteration until both corrections are small
    (Adjigble et al., "Direct 3D visual servoing in the spectral domain", 2022). No
    features, no correspondences. For an unknown rotation use
    :func:`registration_spectral_global`.

    Parameters
    ----------
    {common}
    init : array_like, shape (4, 4), optional
        Initial source-to-target transformation (applied to the source first); an
        ``open3d.core.Tensor`` too.
    option : SpectralRegistrationOption, optional
        Representation and gains.
    criteria : SpectralConvergenceCriteria, optional
        Stopping rule.
    cloud : CloudOption, optional
        Normal estimation and the target's sensor position.
    refinement : RefinementOption or None
        The point-to-plane ICP polish of the law's pose; None returns the law's pose
        itself, correspondence-free (the paper).
    max_correspondence_distance : float, optional
        Distance (metres) at which ``fitness``, ``inlier_rmse`` and ``correspondence_set``
        are measured; the voxel size when omitted.

    Returns
    -------
    SpectralRegistrationResult
        ``transformation`` maps source points onto the target (4x4, float64, rigid).

    Raises
    ------
    ValueError
        For an empty cloud, too few points at this voxel size, NaN or infinite
        coordinates, a voxel size that is not positive or would need more than
        ``option.max_grid_memory``, an ``init`` further than 1e-4 from rigid (nearer, it
        is made exactly rigid) or an array of the wrong shape.
    TypeError
        For an unsupported cloud type, a ``voxel_size`` that is not a real number (a
        string, None, a bool, complex, ``Decimal``), or an ``init`` or cloud array that
        does not hold real numbers (text, a scipy ``Rotation``, complex or bool).

    Examples
    --------
    >>> import open3d as o3d, o3d_spectral
    >>> result = o3d_spectral.registration_spectral(source, target, 0.008)  # doctest: +SKIP
    >>> source.transform(result.transformation)  # doctest: +SKIP
    """
    check_settings(option=option, criteria=criteria, cloud=cloud, refinement=refinement,
                   max_correspondence_distance=max_correspondence_distance)
    clock = StageClock()
    with clock.stage("prepare"):
        run = start(source, target, voxel_size, init, option, criteria, cloud)
    with clock.stage("law"):
        best = Climb(run.moving.centroid)
        run.climb(best, run.criteria.max_iteration)
    result = SpectralRegistrationResult()
    result.translation_peak = best.history[-1].translation_peak
    with clock.stage("polish"):
        result = finish(run, result, best, best.matrix() @ run.init, refinement,
                        max_correspondence_distance)
    result.stage_times = clock.times
    return result


def registration_spectral_global(
    source: object,
    target: object,
    voxel_size: float,
    option: SpectralRegistrationOption | None = None,
    criteria: SpectralConvergenceCriteria | None = None,
    *,
    search: GlobalSearchOption | None = None,
    cloud: CloudOption | None = None,
    refinement: RefinementOption | None = DEFAULT_REFINEMENT,
    max_correspondence_distance: float | None = None,
    device: object | None = None,
) -> SpectralRegistrationResult:
    """Align ``source`` to ``target`` from any relative pose (no initial guess).

    The call runs these stages (each timed in ``result.stage_times`` and logged at INFO):

    1. **prepare**: both clouds down-sampled, their normals, EGIs and the fixed voxel grid;
    2. **candidates**: the correlation of the clouds' Extended Gaussian Images over the
       whole of SO(3) by SO(3) Fourier transforms, its highest peaks (and, between two
       scans, rotations from the grids' spectra) placed by 3D phase correlation and
       ranked by that correlation's peak height; in a scene, searched again around the
       best places (:meth:`o3d_spectral.search.GlobalSearch.rank`);
    3. **confirm**: the best placed pose polished by a short ICP; where it clearly fits
       better than any distinct alternative the search stops here
       (:mod:`o3d_spectral.search.confirmation`, ``result.confirmed``);
       between two scans, the rotations of a sweep of SO(3) are placed (**sweep**) and
       the best confirmed again before any climb;
    4. **climbs**: otherwise the best few are climbed by the paper's control law and
       ranked again, the best climbed on to convergence
       (:meth:`o3d_spectral.search.GlobalSearch.climb`);
    5. **ascent**: between two scans, the best pose turned to where the phase
       correlation's peak is highest (:mod:`o3d_spectral.search.ascent`);
    6. **polish**: the point-to-plane refinement and Open3D's scoring; where the best
       placed pose, as the confirmation polished it, lies clearly closer to the target
       than the result, it is polished and returned instead
       (:func:`o3d_spectral.search.confirmation.closer`);
    7. **turns**: not in a scene, where the returned pose may be wrong (its calibrated
       confidence under one half) and its inliers barely hold a turn about some axis,
       the pose turned about that axis and the best turns polished and measured, the most
       confident whose inliers hold every motion returned
       (:func:`o3d_spectral.opinions.turn_opinion`; ``search.turns``);
    8. **second_opinions**: where the search ran and the returned pose may be wrong (its
       calibrated confidence under one half), the other climbs' poses climbed on,
       polished and measured, and the most confident returned
       (:func:`o3d_spectral.opinions.second_opinion`; ``search.second_opinions``);
    9. **dense_sweep**: on the CPU by default (``search.rotations="escalating"``),
       where the pose may still be wrong: SO(3) swept evenly and ranked up to the
       voxel's own grid (:mod:`o3d_spectral.search.dense`), stages 3-8 run again from
       that ranking, and the more confident of the two results returned.

    Against a single view the search correlates the view with the model as the sensor
    would see it; against a whole scene it focuses on the scene's normals where the
    object was located.

    Parameters
    ----------
    {common}
    option : SpectralRegistrationOption, optional
        Representation and gains of the law.
    criteria : SpectralConvergenceCriteria, optional
        Stopping rule of the final climb (the search's climbs stop at
        ``search.hypothesis_iterations``).
    search : GlobalSearchOption, optional
        Hypotheses, climbs, focus, the Euler grid of the search and how it sweeps SO(3)
        (``rotations``: on the CPU by default the dense search only where the pose is in
        doubt).
    cloud : CloudOption, optional
        Normal estimation and the target's sensor position.
    refinement : RefinementOption or None
        The point-to-plane ICP polish of the pose; None returns the law's pose itself.
    max_correspondence_distance : float, optional
        Distance (metres) at which ``fitness``, ``inlier_rmse`` and ``correspondence_set``
        are measured; the voxel size when omitted.
    device : str or open3d.core.Device, optional
        Where the search's batched correlations run: ``"CPU:0"`` (the default; a
        :class:`PreparedTarget`'s own device when it is the target) or ``"CUDA:0"``
        (CuPy, the ``gpu`` extra), where ``search.rotations="auto"`` sweeps SO(3)
        densely; the law and the polish run on the CPU. A CUDA device that is not usable
        is refused, never replaced by the CPU.

    Returns
    -------
    SpectralRegistrationResult
        ``transformation`` maps source points onto the target (4x4, float64, rigid);
        ``hypotheses`` and ``search_margin`` say how distinct the best pose was;
        ``confidence`` how likely it is to be right.

    Raises
    ------
    ValueError, TypeError
        As :func:`registration_spectral`, and for a ``search.search_samples`` too small
        for the bandwidth.

    Examples
    --------
    >>> result = o3d_spectral.registration_spectral_global(model, scan, 0.008)  # doctest: +SKIP
    """
    check_settings(option=option, criteria=criteria, search=search, cloud=cloud,
                   refinement=refinement, max_correspondence_distance=max_correspondence_distance)
    search = search or GlobalSearchOption()
    search.check_memory(option or SpectralRegistrationOption())  # before any work
    clock = StageClock()
    with clock.stage("prepare"):
        run = start(source, target, voxel_size, np.eye(4), option, criteria, cloud, device)
    finder = GlobalSearch(run.stepper, run.moving, run.target, search, run.situation)
    with clock.stage("candidates"):
        ranking = finder.rank()
    confirmed = _confirmed(finder, ranking, clock)
    if confirmed is None and finder.sweeps:
        with clock.stage("sweep"):  # two scans: the sweep of SO(3) joins the candidates
            ranking = finder.rank(sweep=True)
        confirmed = _confirmed(finder, ranking, clock)
    result = _judged(run, finder, ranking, confirmed, clock, search, refinement,
                     max_correspondence_distance)
    if finder.escalates and may_be_wrong(result.confidence):
        dense = finder.densified()
        with clock.stage("dense_sweep"):
            ranking = dense.rank(sweep=True)
        other = _judged(run, dense, ranking, _confirmed(dense, ranking, clock), clock, search,
                        refinement, max_correspondence_distance)
        if other.confidence > result.confidence:
            result = other
    result.stage_times = clock.times
    return result


def _judged(
    run: Run, finder: GlobalSearch, ranking: Ranking, confirmed: Confirmation | None,
    clock: StageClock, search: GlobalSearchOption, refinement: RefinementOption | None,
    max_correspondence_distance: float | None,
) -> SpectralRegistrationResult:
    """The result of one search from its ``ranking``: the ``confirmed`` pose, or else the
    climbs' and the ascent's; polished, judged, and where it may be wrong, turned and
    given second opinions (stages 4-8 of :func:`registration_spectral_global`)."""
    if confirmed is not None:
        best, pose, result = placed_result(run, confirmed)
    else:
        best, pose, result, _ = searched(run, finder, ranking, clock)
    climbed = list(result.hypotheses)  # before the polish moves them to the caller's frame
    with clock.stage("polish"):
        result = finish(run, result, best, pose @ run.init, refinement,
                        max_correspondence_distance)
        if confirmed is None:  # the best placed pose, where it lies clearly closer
            placed = finder.closer_placed(ranking, run.moving_pose(result.transformation))
            if placed is not None:
                best, pose, result = placed_result(run, placed)
                result = finish(run, result, best, pose @ run.init, refinement,
                                max_correspondence_distance)
    if search.turns and not run.situation.scene and may_be_wrong(result.confidence):
        with clock.stage("turns"):
            result = turn_opinion(run, finder, result, climbed, search.turns, refinement,
                                  max_correspondence_distance)
    if confirmed is None and search.second_opinions and may_be_wrong(result.confidence):
        with clock.stage("second_opinions"):
            result = second_opinion(run, result, climbed, search.second_opinions, refinement,
                                    max_correspondence_distance)
    return result


def _confirmed(finder: GlobalSearch, ranking: Ranking, clock: StageClock) -> Confirmation | None:
    """The confirmation of the best of ``ranking`` where it applies and confirms."""
    if not finder.confirms:
        return None
    with clock.stage("confirm"):
        confirmed = finder.confirm(ranking)
    return confirmed if confirmed.confirmed else None


def placed_result(
    run: Run, placed: Confirmation
) -> tuple[Climb, NDArray[np.float64], SpectralRegistrationResult]:
    """The result of a call that returns a placed hypothesis as the confirmation
    polished it: its pose, with no climb; ``result.confirmed`` as ``placed.confirmed``."""
    result = SpectralRegistrationResult()
    result.confirmed = placed.confirmed
    pose = placed.transformation
    result.hypotheses = [(pose @ run.init, placed.fit)]
    result.search_margin = placed.fit - placed.runner_up
    result.rival_fit = placed.runner_up
    return Climb(run.moving.centroid, converged=True), pose, result


class Searched(NamedTuple):
    """What :func:`searched` leaves: the best climb, the pose (4, 4, before
    ``run.init``: the ascent's where it ran), the result's search fields, and the pose
    the climbs ended at before any ascent."""

    climb: Climb
    pose: NDArray[np.float64]
    result: SpectralRegistrationResult
    climbed: NDArray[np.float64]


def searched(run: Run, finder: GlobalSearch, ranking: Ranking, clock: StageClock) -> Searched:
    """The climbs from the best placed hypotheses and (between two scans) the peak
    ascent, each stage timed on ``clock``."""
    with clock.stage("climbs"):
        climbs = finder.climb(ranking, tolerance=run.criteria.tolerances(run.stepper.voxel_size),
                              max_iteration=run.criteria.max_iteration, init=run.init,
                              start=run.start)
    ranked_iterates = sorted((state.best_iterate() for state in climbs), key=lambda i: -i[0])
    result = SpectralRegistrationResult()
    result.hypotheses = [(M @ run.init, score) for score, M, _ in ranked_iterates]
    result.search_margin = confidence([(score, M) for M, score in result.hypotheses])
    _, climbed, record = ranked_iterates[0]
    pose = climbed
    result.translation_peak = record.translation_peak
    if finder.ascends:
        with clock.stage("ascent"):  # from the best of every climb's best
            ascended = finder.ascend([M for _, M, _ in ranked_iterates])
            pose = ascended.transformation(run.moving.centroid)
            result.translation_peak = ascended.translation_peak
    return Searched(climbs[0], pose, result, climbed)


for _call in (registration_spectral, registration_spectral_global):
    if _call.__doc__:  # None under python -OO
        _call.__doc__ = _call.__doc__.replace("{common}", _COMMON_PARAMETERS)
