"""One control cycle of visual servoing: the global search, then the paper's law.

:class:`ServoLaw` holds the reference cloud's spectra (a
:class:`o3d_spectral.SpectralStepper`) and the state of a servoing run: the EGI smoothing
level, whether the search is still leading, and the law's turn since it took over. Each
:meth:`ServoLaw.step` takes a freshly captured cloud and returns the increments of one
cycle (paper, Algorithm 1, loop body). Needs no simulator.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..law.stepper import Evaluation, MovingCloud, SpectralStepper
from ..options import CloudOption, SpectralRegistrationOption
from ..search import situation
from ..search.ascent import peak_ascent
from ..search.candidates import egi_candidates
from ..search.options import GlobalSearchOption
from ..search.placement import Placements, place
from ..spectra import so3
from ..spectra.rotation import gradient

__all__ = ["Step", "ServoLaw"]


@dataclass(frozen=True)
class Step:
    """Increments of one control cycle for a captured cloud.

    The captured cloud should be moved by ``x -> delta_rotation (x - pivot) + pivot +
    delta_translation`` (equivalently by :attr:`transformation`); a camera that observes
    it moves by the inverse.

    Attributes
    ----------
    delta_rotation : ndarray, shape (3, 3)
        ``exp(lambda_r hat(rotation step))``.
    delta_translation : ndarray, shape (3,)
        ``lambda_t grad_glob T``, metres.
    pivot : ndarray, shape (3,)
        Centroid of the captured cloud, metres.
    evaluation : Evaluation
        Full corrections and costs.
    """

    delta_rotation: NDArray[np.float64]
    delta_translation: NDArray[np.float64]
    pivot: NDArray[np.float64]
    evaluation: Evaluation

    @property
    def transformation(self) -> NDArray[np.float64]:
        """The increment as a 4x4 rigid transform in the cloud's frame."""
        return so3.about_pivot(self.delta_rotation, self.delta_translation, self.pivot)


class ServoLaw:
    """The control law of a servoing run against one reference cloud.

    With a ``search``, the first cycles head for the best hypothesis of the global search
    (:func:`o3d_spectral.search.placement.place`, the whole of SO(3) searched again on each
    capture, the best refined by :func:`o3d_spectral.search.ascent.peak_ascent`, the gains
    applied to its full correction) until it lies within
    ``handover_angle`` of the identity; the law then takes over (:attr:`searching` turns
    False), until its increments add up to a turn over ``law_reach`` (it has left the
    basin it was handed: the search starts again). The law uses the current smoothing
    level (:attr:`level`) and moves to the next finer one once the rotation step is small.
    After its first cycle, it searches each capture's shift in a window of the reference's
    grid about the translation the previous cycle left to do (``translation_window``).

    Parameters
    ----------
    reference : PointCloud, tensor PointCloud or ndarray (N, 3) / (N, 6)
        The cloud captured at the desired pose, metres.
    voxel_size : float
        Metres.
    option : SpectralRegistrationOption, optional
    cloud : CloudOption, optional
    search : GlobalSearchOption or None
        The global search first; None: the paper's law alone.
    handover_angle : float
        Radians.
    law_reach : float
        Radians.
    """

    def __init__(
        self, reference: object, voxel_size: float, *,
        option: SpectralRegistrationOption | None = None, cloud: CloudOption | None = None,
        search: GlobalSearchOption | None = None, handover_angle: float = np.deg2rad(6.0),
        law_reach: float = np.deg2rad(15.0),
    ) -> None:
        self.stepper = SpectralStepper(reference, voxel_size, option=option, cloud=cloud)
        self.search, self.handover_angle, self.law_reach = search, handover_angle, law_reach
        self.reset()

    def reset(self) -> None:
        """Start again from the coarsest smoothing level, and from the global search when
        there is one."""
        self.level = 0
        self.searching = self.search is not None
        self._turned = np.eye(3)  # the law's turn since the handover
        # The translation the last law cycle left to do (metres): the next capture's
        # shift is searched in a window about it (None: over the whole grid).
        self._left: NDArray[np.float64] | None = None

    @property
    def finest(self) -> bool:
        """Whether the next cycle's law uses the finest smoothing level (the stop test
        applies there only)."""
        return self.level == self.stepper.levels - 1

    def step(self, cloud: object) -> Step:
        """One control cycle for a freshly captured cloud (paper, Algorithm 1, loop body).

        Parameters
        ----------
        cloud : PointCloud, tensor PointCloud or ndarray (N, 3) / (N, 6)
            The current cloud, in the reference's frame; not modified.

        Returns
        -------
        Step
        """
        stepper = self.stepper
        moving = stepper.moving(cloud, "cloud")
        if self.searching:
            evaluation = self._towards_best_hypothesis(moving)
            if evaluation is not None:
                return Step(*stepper.increments(evaluation), moving.centroid, evaluation)
            self.searching = False
        around = None if self._left is None else moving.centroid + self._left
        evaluation = stepper.evaluate(moving, level=self.level, around=around)
        self.level = stepper.next_level(self.level, evaluation)
        delta_rotation, delta_translation = stepper.increments(evaluation)
        self._left = evaluation.translation - delta_translation
        if self.search is not None:
            self._turned = delta_rotation @ self._turned
            if so3.rotation_angle(self._turned) > self.law_reach:
                self.reset()  # the law has left the hypothesis' basin: search again
        return Step(delta_rotation, delta_translation, moving.centroid, evaluation)

    def _towards_best_hypothesis(self, moving: MovingCloud) -> Evaluation | None:
        """Full corrections to the best hypothesis (its rotation and where the phase
        correlation puts the turned cloud), or None when its rotation is within
        ``handover_angle`` of the identity (the local law's turn).

        The best placed peak is refined by :func:`o3d_spectral.search.ascent.peak_ascent`
        first: the peaks lie on the correlation's Euler grid, and near the goal the best
        was 6-9 degrees off while the camera was within 1 degree, so the search never
        handed over (seed 29 ran out of time at 1.7 degrees)."""
        stepper, search = self.stepper, self.search
        placed = place(stepper, moving, egi_candidates(stepper, moving, search), Placements(),
                       two_scans=situation(stepper, moving).two_scans,
                       coarse_placements=search.coarse_placements, workers=search.workers)[0]
        best = peak_ascent(self.stepper, moving, placed.transformation(moving.centroid))
        rotation = so3.log(best.rotation)
        if np.linalg.norm(rotation) <= self.handover_angle:
            return None
        local = gradient(*self.stepper.rotation_spectra(moving), best.rotation)
        return Evaluation.of(
            best.centre - moving.centroid, rotation, local, best.translation_peak,
            best.cost_translation,
        )
