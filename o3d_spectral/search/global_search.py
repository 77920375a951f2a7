"""The search over all of SO(3) as one object: its stages, and the state they share.

The paper's law is a local gradient ascent. :class:`GlobalSearch` starts it from many
places instead, in stages that :func:`o3d_spectral.registration_spectral_global` runs in
turn:

1. :meth:`GlobalSearch.rank` — **candidates** (:mod:`o3d_spectral.search.candidates`)
   placed by phase correlation and ranked by its peak height
   (:mod:`o3d_spectral.search.placement`); in a scene, the fixed EGI is then focused on a
   ball about each of the best distinct places and searched again there; between two
   scans, with ``sweep=True``, the sweep of SO(3) joins the candidates;
2. :meth:`GlobalSearch.confirm` — the best placed pose polished briefly and confirmed by
   its fit and its closeness against distinct rivals (:mod:`o3d_spectral.search.confirmation`);
3. :meth:`GlobalSearch.climb` — otherwise the best few climbed by the law and ranked by
   their best iterate, the best climbed on to convergence (:mod:`o3d_spectral.search.climbs`);
4. :meth:`GlobalSearch.ascend` — between two scans, the best poses turned to where the
   phase correlation's peak is highest (:mod:`o3d_spectral.search.ascent`);
5. :meth:`GlobalSearch.closer_placed` — after the polish, the best placed pose as the
   confirmation polished it, where it lies clearly closer to the fixed cloud;
6. :meth:`GlobalSearch.densified` — where the result may be wrong and the search
   :attr:`~GlobalSearch.escalates`, the same search with the dense sweep, its stages run
   again from the ranking on.

Which stages run, and how, follows the :class:`~o3d_spectral.search.situation.Situation`
decided once from the clouds. What the stages measure is kept in one
:class:`SearchState`, so that a ranking made again (after the sweep) places and polishes
only what is new.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
from functools import cached_property
from typing import NamedTuple

import numpy as np
import open3d as o3d
from numpy.typing import NDArray

from ..evidence.fit import Fit, fit
from ..evidence.poses import distinct
from ..io.cloud import CloudArrays, to_legacy
from ..law.loop import Climb, climb
from ..law.stepper import MovingCloud, SpectralStepper
from ..refinement.icp import thinned, with_normals
from .ascent import PRESELECT_SPAN, best_ascent
from .candidates import Candidate, egi_candidates, shell_candidates, swept_candidates
from .climbs import FOCUS_MARGIN, climbed
from .confirmation import FIXED_CELL, Confirmation, closer, confirm
from .dense import dense_candidates
from .options import GlobalSearchOption
from .placement import PLACEMENT_SPAN, Hypothesis, Placements, best_first, place, places
from .situation import Situation

__all__ = ["GlobalSearch", "SearchState", "Ranking"]


class Ranking(NamedTuple):
    """Placed hypotheses, best first, and whether the EGI was focused on places in a
    scene (each climb then matches the scene's normals near its own points only)."""

    hypotheses: list[Hypothesis]
    focus: bool


@dataclass
class SearchState:
    """What the stages of one search measured, for the stages after them.

    Attributes
    ----------
    candidates : list of Candidate or None
        The EGI's (and between two scans the shells') candidates, once made.
    placements : Placements
        Coarse scores and placements by candidate key.
    fits : dict
        The confirmation's polished fits (:class:`~o3d_spectral.evidence.fit.Fit`)
        by hypothesis key.
    """

    candidates: list[Candidate] | None = None
    placements: Placements = field(default_factory=Placements)
    fits: dict[tuple, Fit] = field(default_factory=dict)


class GlobalSearch:
    """The global search of one moving cloud against one fixed cloud.

    Parameters
    ----------
    stepper : SpectralStepper
        The fixed cloud's spectra.
    moving : MovingCloud
        The moving cloud, prepared.
    target : CloudArrays
        The fixed cloud as given (metres), for the confirmation's polish.
    option : GlobalSearchOption
    situation : Situation
        The kind of problem (:func:`o3d_spectral.search.situation.situation`).
    """

    def __init__(
        self, stepper: SpectralStepper, moving: MovingCloud, target: CloudArrays,
        option: GlobalSearchOption, situation: Situation,
    ) -> None:
        self.stepper, self.moving, self.target = stepper, moving, target
        self.option, self.situation = option, situation
        self.rotations = option.sweep_on(stepper.device.gpu)  # "auto" resolved
        self.state = SearchState()

    @property
    def sweeps(self) -> bool:
        """Whether :meth:`rank` with ``sweep=True`` adds a sweep of SO(3): the dense
        search (:attr:`rotations` ``"dense"``); otherwise two scans, and
        ``option.sweep_rotations`` over 0."""
        return self.rotations == "dense" or (self.situation.two_scans
                                             and self.option.sweep_rotations > 0)

    @property
    def escalates(self) -> bool:
        """Whether a doubtful result of this search is searched again by
        :meth:`densified`: :attr:`rotations` ``"escalating"``."""
        return self.rotations == "escalating"

    def densified(self) -> GlobalSearch:
        """This search as the dense one (:attr:`rotations` ``"dense"``), sharing what it
        has measured: its candidates, placements and polished fits are not made again."""
        dense = copy.copy(self)  # the same state and fixed cloud
        dense.rotations = "dense"
        return dense

    @property
    def confirms(self) -> bool:
        """Whether :meth:`confirm` applies: ``option.confirm``, and not in a scene."""
        return self.option.confirm and not self.situation.scene

    @property
    def ascends(self) -> bool:
        """Whether :meth:`ascend` applies: two scans, and ``option.peak_ascent``."""
        return self.option.peak_ascent and self.situation.two_scans

    @cached_property
    def fixed(self) -> o3d.geometry.PointCloud:
        """The fixed cloud with normals (estimated ones where it had none), one point per
        cell of :data:`~o3d_spectral.search.confirmation.FIXED_CELL` voxels, for the
        confirmation's polish."""
        fixed = with_normals(to_legacy(self.target), self.stepper.target_normal_points,
                             self.stepper.target_normals)
        return thinned(fixed, FIXED_CELL * self.stepper.voxel_size)

    def rank(self, *, sweep: bool = False) -> Ranking:
        """The candidates placed and (in a scene) focused, best placed first."""
        stepper, moving, option = self.stepper, self.moving, self.option
        if self.state.candidates is None:
            candidates = egi_candidates(stepper, moving, option)
            if option.egi_focus and self.situation.scene:  # they only find the places
                candidates = candidates[: option.scene_hypotheses]
            if self.situation.two_scans and option.shell_hypotheses:
                candidates += shell_candidates(stepper.target_points, moving.points,
                                               option.shell_hypotheses)
            self.state.candidates = candidates
        candidates, ranked_already = list(self.state.candidates), []
        if sweep and self.sweeps:
            if self.rotations == "dense":
                ranked_already = dense_candidates(stepper, moving, option.dense_rotations,
                                                  two_scans=self.situation.two_scans,
                                                  workers=option.workers)
            else:
                candidates += swept_candidates(stepper, moving, option.sweep_rotations,
                                               option.workers)
        ranked = place(stepper, moving, candidates, self.state.placements,
                       two_scans=self.situation.two_scans,
                       coarse_placements=option.coarse_placements, workers=option.workers)
        if ranked_already:  # ranked on the placement's grid: placed, none left out
            ranked = best_first(ranked + place(
                stepper, moving, ranked_already, self.state.placements,
                two_scans=self.situation.two_scans, workers=option.workers))
        if not option.egi_focus:
            return Ranking(ranked, False)
        return self._focused(ranked)

    def _focused(self, ranked: list[Hypothesis]) -> Ranking:
        """``ranked`` and the hypotheses of the EGI focused on each of the
        ``option.focus_places`` best places (a ball :data:`FOCUS_MARGIN` voxels wider
        than the moving cloud), best first."""
        stepper, moving = self.stepper, self.moving
        radius = moving.radius + FOCUS_MARGIN * stepper.voxel_size
        focus = False
        for located in places(ranked, moving.radius)[: self.option.focus_places]:
            ball = stepper.focused(located[None, :], radius)
            if ball is stepper:  # the fixed cloud is about the moving one's size
                break
            focus = True
            ranked = ranked + place(ball, moving, egi_candidates(ball, moving, self.option),
                                    self.state.placements, around=located,
                                    workers=self.option.workers)
        return Ranking(best_first(ranked), focus)

    def confirm(self, ranking: Ranking) -> Confirmation:
        """The confirmation of the best of ``ranking``
        (:func:`o3d_spectral.search.confirmation.confirm`); apply it where
        :attr:`confirms`."""
        return confirm(self.stepper, self.moving, self.fixed, ranking.hypotheses,
                       fits=self.state.fits, workers=self.option.workers)

    def climb(
        self, ranking: Ranking, *, tolerance: tuple[float, float], max_iteration: int,
        init: NDArray[np.float64], start: float,
    ) -> list[Climb]:
        """The ``option.climbs`` best of ``ranking`` climbed ``option.hypothesis_iterations``
        times (at most ``max_iteration``), best first, the best climbed on for the rest of
        ``max_iteration``; ``tolerance``, ``init``, ``start`` as for
        :func:`o3d_spectral.law.loop.climb`."""
        climbs = climbed(
            self.stepper, self.moving, ranking.hypotheses[: self.option.climbs],
            focus=ranking.focus, egi_scored=not self.situation.two_scans,
            iterations=min(self.option.hypothesis_iterations, max_iteration),
            tolerance=tolerance, init=init, start=start, workers=self.option.workers,
        )
        best = climbs[0]
        climb(best.stepper, self.moving, best.state, max_iteration - len(best.state.history),
              tolerance, init, start)
        return [c.state for c in climbs]

    def ascend(self, poses: list[NDArray[np.float64]]) -> Hypothesis:
        """The most promising of ``poses`` (4, 4, best first) turned to where the
        phase-correlation peak is highest (:func:`o3d_spectral.search.ascent.best_ascent`),
        told apart on the placement's grid after the dense search (which ranked them
        there: on a grid twice as coarse, a pose 15 degrees off outscored one 1.6 degrees
        off on the dragon scans 120 degrees apart), on a coarser one otherwise; apply it
        where :attr:`ascends`."""
        span = PLACEMENT_SPAN if self.rotations == "dense" else PRESELECT_SPAN
        return best_ascent(self.stepper, self.moving, poses, self.option.workers, span)

    def closer_placed(self, ranking: Ranking, pose: NDArray[np.float64]) -> Confirmation | None:
        """The best placed hypothesis as the confirmation polished it, where it lies
        clearly closer to the fixed cloud than ``pose`` (4, 4, the moving cloud onto the
        fixed one; :func:`o3d_spectral.search.confirmation.closer`), with ``pose``'s fit
        as its rival's when the two are distinct; None otherwise, or where no
        confirmation measured it (a scene)."""
        placed = self.state.fits.get(ranking.hypotheses[0].key)
        if placed is None:
            return None
        returned = fit(self.stepper, self.moving, self.fixed, pose, polish=False)
        if not closer(placed, returned):
            return None
        rival = returned.share if distinct(pose, placed.pose) else 0.0
        return Confirmation(placed.pose, placed.share, rival, confirmed=False)
