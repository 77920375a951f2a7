"""The law climbed from the best placed hypotheses (the paper's law as a local search)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from ..common.parallel import thread_map
from ..law.loop import Climb, climb
from ..law.stepper import MovingCloud, SpectralStepper
from .constants import FOCUS_MARGIN
from .placement import Hypothesis

__all__ = ["Climbed", "climbed", "FOCUS_MARGIN"]


class Climbed(NamedTuple):
    """A climb of the law and the spectra it climbs against.

    Attributes
    ----------
    state : Climb
    stepper : SpectralStepper
        The registration's, or in a scene the one focused about the climb's start
        (:meth:`o3d_spectral.SpectralStepper.focused`): continue the climb against it.
    """

    state: Climb
    stepper: SpectralStepper


def climbed(
    stepper: SpectralStepper, moving: MovingCloud, starts: list[Hypothesis], *,
    focus: bool, egi_scored: bool, iterations: int, tolerance: tuple[float, float],
    init: NDArray[np.float64], start: float, workers: int | None = 1,
) -> list[Climbed]:
    """The law climbed ``iterations`` times from each of ``starts`` (on ``workers``
    threads), best first.

    Parameters
    ----------
    stepper : SpectralStepper
    moving : MovingCloud
    starts : list of Hypothesis
        Placed hypotheses to climb from.
    focus : bool
        Whether the EGI was focused on places in a scene: each climb then matches the
        scene's normals within :data:`FOCUS_MARGIN` voxels of its own points only.
    egi_scored : bool
        Whether the climbs' iterates are scored with the EGI correlation
        (:class:`o3d_spectral.law.loop.Climb`).
    iterations : int
    tolerance, init, start
        As for :func:`o3d_spectral.law.loop.climb`.
    workers : int or None
        Threads (all cores when None).

    Returns
    -------
    list of Climbed
        The climbs, by their best iterate's score
        (:meth:`o3d_spectral.law.loop.Climb.best_iterate`), best first.
    """
    def climbed_from(hypothesis: Hypothesis) -> Climbed:
        state = hypothesis.climb(moving, egi_scored=egi_scored)
        against = stepper
        if focus:  # the scene's normals near this hypothesis' own points
            near, _, _ = stepper.visible(moving, state.R, state.T)
            against = stepper.focused(near, FOCUS_MARGIN * stepper.voxel_size)
        climb(against, moving, state, iterations, tolerance, init, start)
        return Climbed(state, against)

    climbs = thread_map(climbed_from, starts, workers)
    return sorted(climbs, key=lambda c: -c.state.best_iterate()[0])
