"""The search over all of SO(3): candidates, placement, focus, climbs and ranking.

The paper's law is a local gradient ascent. From an unknown pose,
:func:`ranked_hypotheses` and :func:`climbed` start it from many places instead:

1. **Candidates**: the highest peaks of the rotation correlation evaluated over the whole
   of SO(3) by SO(3) Fourier transforms (:meth:`o3d_spectral.SpectralStepper.rotation_grid`);
   for two single views, also those of the correlation of their voxel grids' spectra on
   spherical shells (:func:`shell_rotations`) and the best of a sweep of rotations spread
   evenly over SO(3), ranked by a coarse phase correlation (:func:`swept_rotations`).
2. **Placement**: each candidate rotation is placed by one phase correlation and scored by
   that correlation's peak height (how well the turned grid matches under any shift):
   :func:`hypotheses`. Between two views, all the candidates are ranked on a coarse grid
   first and only the best are placed at full resolution.
3. **Focus**: in a scene larger than the moving cloud, the scene's EGI is restricted to a
   ball about each of the best distinct places (:func:`places`) and searched again there.
   Only the whole EGI's ``scene_hypotheses`` highest peaks are placed over the whole
   scene: they only have to find the places.
4. **Climbs** (:func:`climbed`): unless the best placed hypothesis was confirmed
   (:mod:`o3d_spectral.confirmation`), the best hypotheses are climbed a few iterations
   by the law (:func:`o3d_spectral.law.climb`) and ranked by their best iterate
   (:meth:`o3d_spectral.law.Climb.best_iterate`).

The registration then climbs the best on to convergence and returns the best-scoring
iterate of all the climbs, with :func:`confidence`.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .law import Climb, climb
from .options import GlobalSearchOption
from .parallel import thread_map
from .spectra import so3
from .spectra.shells import SHELL_BANDWIDTH, shell_coefficients, shell_voxel
from .spectra.so3fft import correlation_grid, peaks
from .spectra.target_grid import COARSE_FACTOR
from .stepper import MovingCloud, SpectralStepper

__all__ = [
    "Hypothesis", "hypotheses", "egi_rotations", "shell_rotations", "swept_rotations", "places",
    "ranked_hypotheses", "sweeps", "climbed", "confidence", "DISTINCT_ANGLE", "FOCUS_MARGIN",
    "SWEEP_FACTOR", "SWEEP_SPAN", "SWEEP_PLACEMENTS", "PLACEMENT_SPAN", "span_factor",
    "SWEEP_SENSOR_ANGLE", "placed_peaks",
]

#: Rotations further apart than this (radians) are distinct hypotheses (confidence).
DISTINCT_ANGLE = np.deg2rad(10.0)
#: Voxels of the grid the sweep's rotations are first placed on (:func:`swept_rotations`:
#: a 27th of the FFT; a true rotation 10-15 degrees off the nearest swept one still
#: placed best or nearly on the dragon scans, 44-54 voxels across) ...
SWEEP_FACTOR = 3.0
#: ... or more, so that the moving cloud spans at most this many of its cells: the cost
#: of each placement bounded whatever the clouds' size (two 1.6 m RGB-D frames at 1 cm:
#: 9 cm cells; before this bound, the sweep and its placements added 18 s there).
SWEEP_SPAN = 18.0
#: Between two views, candidates are placed on a grid where the moving cloud spans at
#: most this many cells: the voxel itself for the dragon scans (44-54 voxels across) and
#: the servo's tabletop captures (74-80); two 1.6 m RGB-D frames at 1 cm placed each of
#: their 48 candidates in 0.27 s at the voxel, in a tenth of that on 2.5-voxel cells.
PLACEMENT_SPAN = 96.0
#: The sweep's rotations that join the other candidates.
SWEEP_PLACEMENTS = 16
#: Largest angle (radians) between the two views' sensor directions the sweep tries
#: (from the normals, :func:`o3d_spectral.io.normals.view_direction`: 62-86 degrees on
#: dragon scans 48-72 degrees apart); scans from further apart share little surface.
SWEEP_SENSOR_ANGLE = np.deg2rad(110.0)
#: Voxels added to the moving cloud's radius for the ball of a focused EGI, and the
#: distance (voxels) from a hypothesis' points of the normals its climb matches.
FOCUS_MARGIN = 2.0


@dataclass(frozen=True)
class Hypothesis:
    """A peak of the rotation correlation over SO(3), placed by phase correlation.

    The moving cloud fits the fixed one at ``x -> rotation (x - c) + centre`` (``c``:
    its centroid).

    Attributes
    ----------
    rotation : ndarray, shape (3, 3)
        The peak's rotation, about the moving cloud's centroid.
    centre : ndarray, shape (3,)
        Where the phase correlation puts the turned cloud's centroid, metres.
    translation_peak : float
        Height of that phase-correlation peak in [0, 1]: the hypothesis' score.
    cost_translation : float
        ``J_t`` of the turned cloud before that shift, in [0, 2].
    """

    rotation: NDArray[np.float64]
    centre: NDArray[np.float64]
    translation_peak: float
    cost_translation: float

    def climb(self, moving: MovingCloud, *, egi_scored: bool = True) -> Climb:
        """A climb of the law starting at this hypothesis (see :class:`Climb`)."""
        return Climb(moving.centroid, self.rotation, self.centre - moving.centroid,
                     predicted=self.centre, egi_scored=egi_scored)

    def transformation(self, centroid: NDArray[np.float64]) -> NDArray[np.float64]:
        """The hypothesis as a 4x4 rigid transform of a moving cloud whose centroid is
        ``centroid`` (3,), metres."""
        return so3.about_pivot(self.rotation, self.centre - centroid, centroid)


def hypotheses(
    stepper: SpectralStepper, moving: MovingCloud, search: GlobalSearchOption, *,
    around: ArrayLike | None = None, memo: dict | None = None,
) -> list[Hypothesis]:
    """The ``search.hypotheses`` highest peaks of ``C_r`` over SO(3), each placed by phase
    correlation (near ``around``, metres, when given), highest placed peak first;
    ``memo``: placements kept from other searches on the same clouds (:func:`_placed`)."""
    rotations = egi_rotations(stepper, moving, search)
    return _placed(stepper, moving, rotations, around, search.coarse_placements,
                   two_views=stepper.two_views(moving), workers=search.workers, memo=memo)


def egi_rotations(
    stepper: SpectralStepper, moving: MovingCloud, search: GlobalSearchOption
) -> list[tuple[NDArray[np.float64], float]]:
    """The ``search.hypotheses`` highest peaks of ``C_r`` over SO(3) (rotation, value),
    highest first (:meth:`o3d_spectral.SpectralStepper.rotation_grid`)."""
    grid = stepper.rotation_grid(
        moving, search.samples(stepper.option.bandwidth), visibility=search.search_visibility
    )
    return peaks(grid, count=search.hypotheses)


def shell_rotations(
    stepper: SpectralStepper, moving: MovingCloud, count: int
) -> list[tuple[NDArray[np.float64], float]]:
    """The ``count`` highest peaks over SO(3) (rotation, value) of the correlation of the
    two clouds' spectra on spherical shells (:mod:`o3d_spectral.spectra.shells`), highest first."""
    voxel = shell_voxel(stepper.target_points, moving.points)
    grid = correlation_grid(
        shell_coefficients(moving.points, voxel), shell_coefficients(stepper.target_points, voxel),
        n_alpha=2 * SHELL_BANDWIDTH, n_beta=2 * SHELL_BANDWIDTH,
    )
    return peaks(grid, count=count)


def span_factor(stepper: SpectralStepper, moving: MovingCloud, span: float) -> float:
    """The grid factor (voxels, at least 1, in steps of half a voxel so that clouds of
    about one size share their coarse grids) at which the moving cloud spans at most
    ``span`` cells across (:meth:`o3d_spectral.SpectralStepper.locate`'s ``factor``):
    searches that place many rotations keep their cost bounded whatever the clouds' size."""
    return max(1.0, np.ceil(4.0 * moving.radius / (span * stepper.voxel_size)) / 2.0)


def swept_rotations(
    stepper: SpectralStepper, moving: MovingCloud, count: int, workers: int | None = 1
) -> list[tuple[NDArray[np.float64], float]]:
    """For two single views: the :data:`SWEEP_PLACEMENTS` rotations, of ``count`` spread
    evenly over SO(3), that place best by phase correlation on a coarse grid (rotation,
    peak height), best first.

    Of the ``count`` rotations of :func:`o3d_spectral.spectra.so3.uniform_rotations`, those that
    turn the moving view's sensor direction within :data:`SWEEP_SENSOR_ANGLE` of the
    fixed view's are placed on a grid of :data:`SWEEP_FACTOR` voxels (coarser for a
    moving cloud over :data:`SWEEP_SPAN` of those across), on ``workers`` threads. Two
    scans far enough apart share too little of their normals for the EGI's peaks to hold
    their rotation (dragon scans 48 and 96 degrees: none of the 200 highest within 100
    degrees of it, none of the shells' within 50); the peak of a phase correlation,
    which compares the shapes themselves, is highest there (0.37 on a grid of 2 voxels,
    against at most 0.23 for the EGI's candidates).
    """
    rotations = so3.uniform_rotations(count)
    toward = rotations @ moving.reading.view @ stepper.target_reading.view
    rotations = rotations[toward >= np.cos(SWEEP_SENSOR_ANGLE)]
    factor = max(SWEEP_FACTOR, span_factor(stepper, moving, SWEEP_SPAN))
    scores = placed_peaks(stepper, moving, rotations, factor, workers)
    best = np.argsort(-scores, kind="stable")[:SWEEP_PLACEMENTS]
    return [(rotations[i], float(scores[i])) for i in best]


def placed_peaks(
    stepper: SpectralStepper, moving: MovingCloud, rotations: Iterable[NDArray[np.float64]],
    factor: float = 1.0, workers: int | None = 1,
) -> NDArray[np.float64]:
    """The phase-correlation peak heights of the moving cloud turned by each rotation
    (3, 3) about its centroid and placed anywhere on a grid of ``factor`` voxels:
    :meth:`o3d_spectral.SpectralStepper.locate`'s for each, batched
    (:meth:`o3d_spectral.spectra.target_grid.TargetGrid.peaks`), the batches on
    ``workers`` threads (the same heights whatever the threads)."""
    grid, rotations = stepper.grid.coarsened(factor), list(rotations)
    size = grid.peaks_batch(moving.radius)

    def heights(batch: list[NDArray[np.float64]]) -> NDArray[np.float64]:
        moved = (stepper.visible(moving, R, np.zeros(3))[0] for R in batch)
        return grid.peaks(moved, moving.radius, moving.centroid)

    batches = [rotations[i : i + size] for i in range(0, len(rotations), size)]
    return np.concatenate([np.zeros(0), *thread_map(heights, batches, workers)])


def _placed(
    stepper: SpectralStepper, moving: MovingCloud, rotations: list[tuple[NDArray, float]],
    around: ArrayLike | None, coarse_placements: int = 0, *, two_views: bool = False,
    workers: int | None = 1, memo: dict | None = None,
) -> list[Hypothesis]:
    """``rotations`` (from :func:`o3d_spectral.spectra.so3fft.peaks`) placed by phase correlation
    near ``around`` (anywhere when None), highest placed peak first. Placed anywhere
    between ``two_views`` (:meth:`o3d_spectral.SpectralStepper.two_views`): on a grid
    where the moving cloud spans at most :data:`PLACEMENT_SPAN` cells, and only the
    ``coarse_placements`` (when over 0) that place best on one twice as coarse
    (:meth:`o3d_spectral.SpectralStepper.locate`) are kept; ``memo`` (a dict, kept across
    calls on the same clouds) holds those coarse scores and the placements, by rotation
    and the block of the fixed grid searched, so that a rotation is placed once on a
    block however often it is ranked (near a place whose search covers the whole grid, a
    focused peak the whole EGI also had is placed once). Placed on ``workers`` threads
    (:func:`o3d_spectral.parallel.thread_map`)."""
    factor = 1.0
    memo = {} if memo is None else memo
    if around is None and two_views:
        factor = span_factor(stepper, moving, PLACEMENT_SPAN)
        if 0 < coarse_placements < len(rotations):
            coarse = COARSE_FACTOR * factor
            new = [R for R, _ in rotations if ("coarse", R.tobytes()) not in memo]
            scores = placed_peaks(stepper, moving, new, coarse, workers)
            for R, score in zip(new, scores, strict=True):
                memo["coarse", R.tobytes()] = score
            scores = np.array([memo["coarse", R.tobytes()] for R, _ in rotations])
            best = np.argsort(-scores, kind="stable")[:coarse_placements]
            rotations = [rotations[i] for i in np.sort(best)]

    def placed(R: NDArray[np.float64]) -> Hypothesis:
        centre, peak, cost = stepper.locate(moving, R, around=around, factor=factor)
        return Hypothesis(R, centre, peak, cost)

    grid = stepper.grid.coarsened(factor)
    block = grid.search_box(moving.radius, around)  # the block locate searches
    searched = (factor, None if block is grid.box else tuple(block.offset))
    new = [R for R, _ in rotations if ("placed", R.tobytes(), searched) not in memo]
    for R, hypothesis in zip(new, thread_map(placed, new, workers), strict=True):
        memo["placed", R.tobytes(), searched] = hypothesis
    return _best_first([memo["placed", R.tobytes(), searched] for R, _ in rotations])


def _best_first(found: list[Hypothesis]) -> list[Hypothesis]:
    """``found`` by placed peak height, highest first (a stable sort: equals keep their
    order)."""
    return sorted(found, key=lambda h: -h.translation_peak)


def places(ranked: list[Hypothesis], separation: float) -> list[NDArray[np.float64]]:
    """Where the ranked hypotheses put the moving cloud's centroid (metres), best first,
    each over ``separation`` (metres) from the ones before."""
    found: list[NDArray[np.float64]] = []
    for h in ranked:
        if all(np.linalg.norm(h.centre - p) > separation for p in found):
            found.append(h.centre)
    return found


def _focused_hypotheses(
    stepper: SpectralStepper, moving: MovingCloud, search: GlobalSearchOption,
    ranked: list[Hypothesis], memo: dict,
) -> tuple[list[Hypothesis], bool]:
    """``ranked`` and the hypotheses of the EGI focused on each of the
    ``search.focus_places`` best places, best first; and whether any focus applied.
    ``memo``: the placements made (:func:`_placed`)."""
    radius = moving.radius + FOCUS_MARGIN * stepper.voxel_size
    focus = False
    for located in places(ranked, moving.radius)[: search.focus_places]:
        ball = stepper.focused(located[None, :], radius)
        if ball is stepper:  # the fixed cloud is about the moving one's size
            break
        focus = True
        ranked = ranked + hypotheses(ball, moving, search, around=located, memo=memo)
    return _best_first(ranked), focus


def ranked_hypotheses(
    stepper: SpectralStepper, moving: MovingCloud, search: GlobalSearchOption, *,
    sweep: bool = True, memo: dict | None = None,
) -> tuple[list[Hypothesis], bool]:
    """Steps 1-3 of the search: the candidates, placed and (in a scene) focused, best
    placed first; and whether any focus applied (the climbs then match the scene's normals
    near each hypothesis only).

    Parameters
    ----------
    stepper, moving, search
    sweep : bool
        Between two views, add the sweep's rotations (:func:`swept_rotations`) to the
        candidates (with ``search.sweep_rotations`` over 0).
    memo : dict, optional
        Candidates and placements kept from an earlier call on the same clouds and
        ``search`` (:func:`_placed`): the registration ranks the candidates without the
        sweep first and, where that confirms nothing, again with it, placing only what is
        new.
    """
    memo = {} if memo is None else memo
    two_views = stepper.two_views(moving)
    if "candidates" not in memo:
        rotations = egi_rotations(stepper, moving, search)
        if search.egi_focus and stepper.grid.holds_more(moving.radius):  # they find places
            rotations = rotations[: search.scene_hypotheses]
        if two_views and search.shell_hypotheses:
            rotations += shell_rotations(stepper, moving, search.shell_hypotheses)
        memo["candidates"] = rotations
    rotations = list(memo["candidates"])
    if sweep and sweeps(stepper, moving, search):
        rotations += swept_rotations(stepper, moving, search.sweep_rotations, search.workers)
    ranked = _placed(stepper, moving, rotations, None, search.coarse_placements,
                     two_views=two_views, workers=search.workers, memo=memo)
    if not search.egi_focus:
        return ranked, False
    return _focused_hypotheses(stepper, moving, search, ranked, memo)


def sweeps(stepper: SpectralStepper, moving: MovingCloud, search: GlobalSearchOption) -> bool:
    """Whether :func:`ranked_hypotheses` adds a sweep of SO(3) (two views, and
    ``search.sweep_rotations`` over 0)."""
    return stepper.two_views(moving) and search.sweep_rotations > 0


def climbed(
    stepper: SpectralStepper, moving: MovingCloud, search: GlobalSearchOption,
    ranked: list[Hypothesis], focus: bool, *, iterations: int, tolerance: tuple[float, float],
    init: NDArray[np.float64], start: float,
) -> list[Climb]:
    """Step 4 of the search: the ``search.climbs`` best of ``ranked`` climbed a little by the
    law (on ``search.workers`` threads), best first.

    Parameters
    ----------
    stepper : SpectralStepper
    moving : MovingCloud
    search : GlobalSearchOption
    ranked : list of Hypothesis
        Placed hypotheses, best first (:func:`ranked_hypotheses`).
    focus : bool
        Whether the EGI was focused on places in a scene (:func:`ranked_hypotheses`): each
        climb then matches the scene's normals near its own points only.
    iterations : int
        Iterations of each climb (at most ``search.hypothesis_iterations``).
    tolerance, init, start
        As for :func:`o3d_spectral.law.climb`.

    Returns
    -------
    list of Climb
        The climbs, by their best iterate's score
        (:meth:`o3d_spectral.law.Climb.best_iterate`), best first.
    """
    two_views = stepper.two_views(moving)
    def climbed_from(hypothesis: Hypothesis) -> Climb:
        state = hypothesis.climb(moving, egi_scored=not two_views)
        if focus:  # the scene's normals near this hypothesis' own points, kept for its climb
            near, _, _ = stepper.visible(moving, state.R, state.T)
            state.stepper = stepper.focused(near, FOCUS_MARGIN * stepper.voxel_size)
        climb(stepper, moving, state, iterations, tolerance, init, start)
        return state

    climbs = thread_map(climbed_from, ranked[: search.climbs], search.workers)
    return sorted(climbs, key=lambda state: -state.best_iterate()[0])


def confidence(ranked: list[tuple[float, NDArray[np.float64]]]) -> float:
    """Best score minus the best score of a transformation over ``DISTINCT_ANGLE`` away
    (in rotation) from the best; the best score when every one is near it. ``ranked``:
    (score, 4x4 transformation), best first."""
    best_score, best = ranked[0]
    for score, other in ranked[1:]:
        if so3.rotation_angle(other[:3, :3].T @ best[:3, :3]) > DISTINCT_ANGLE:
            return best_score - score
    return best_score
