"""Early confirmation of the search's best placed hypothesis: stop where it is clear.

The global search places the rotation correlation's peaks by phase correlation
(:mod:`o3d_spectral.search.placement`); on most calls the best placed one is
already right and the law's climbs only refine it. :func:`confirm` tells those calls
apart before the climbs run, the way RANSAC stops once a hypothesis is verified:

1. the best placed hypothesis is polished by a short point-to-plane ICP (a pass at two
   voxels, then one at one voxel) of the moving cloud's one-point-per-voxel points that
   the fixed cloud's sensor would see there, against the fixed cloud near that pose;
2. its *fit* is the share of those points within one voxel of the fixed cloud after the
   polish (Open3D's ``fitness`` on the visible points), and its *closeness* the share
   within a quarter voxel of the fixed surface's tangent plane at their nearest point
   (:func:`o3d_spectral.evidence.fit.fit`; the fixed cloud is thinned to half-voxel
   cells: the plane, not the spacing of its points, says how close the surfaces are);
3. the next placed hypotheses are polished and measured the same way; those whose
   polished pose is :func:`~o3d_spectral.evidence.poses.distinct` from the best's are its
   rivals (a start that the polish brings to the same pose is none).

The pose is confirmed when its fit reaches :data:`MIN_FIT` (enough of the cloud is
there) and no rival lies closer to the fixed cloud; never in a scene
(:class:`~o3d_spectral.search.situation.Kind`: there a flat face fits a table or a box
beside the object as well as the object itself, and the places not climbed yet are not
compared).
The fit's two scales do two jobs (:mod:`o3d_spectral.evidence.fit`): a rival as close as
the best is a symmetry at the scale the data can tell, and either pose is right. Both
numbers are calibrated for precision, not for the share of calls that stop
(``eval/bench_speed.py`` reports both on every group): a view that does not show what
tells two poses apart (a mug's handle) is never confirmed, since a distinct alternative
then fits as closely, and the whole search runs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import open3d as o3d
from numpy.typing import NDArray

from ..common.parallel import resolved_workers, thread_map
from ..evidence.fit import Fit, fit
from ..evidence.poses import distinct
from ..law.stepper import MovingCloud, SpectralStepper
from .constants import CANDIDATES, CLOSER_MARGIN, FIXED_CELL, MIN_FIT
from .placement import Hypothesis

__all__ = ["Confirmation", "confirm", "closer", "MIN_FIT", "CLOSER_MARGIN", "CANDIDATES",
           "FIXED_CELL"]


@dataclass(frozen=True)
class Confirmation:
    """The outcome of :func:`confirm`.

    Attributes
    ----------
    transformation : ndarray, shape (4, 4)
        The best placed hypothesis after the short polish (moving cloud to fixed cloud).
    fit : float
        Its fit in [0, 1]: the share of its visible points within one voxel.
    runner_up : float
        The best fit of a distinct alternative (0 when none was placed).
    confirmed : bool
        ``fit >= MIN_FIT`` and no distinct alternative closer
        (:class:`~o3d_spectral.evidence.fit.Fit`).
    """

    transformation: NDArray[np.float64]
    fit: float
    runner_up: float
    confirmed: bool


def confirm(
    stepper: SpectralStepper, moving: MovingCloud, fixed: o3d.geometry.PointCloud,
    ranked: list[Hypothesis], *, fits: dict | None = None, workers: int | None = 1,
) -> Confirmation:
    """Whether the best of ``ranked`` (placed hypotheses, best first) is clearly right.

    Parameters
    ----------
    stepper, moving
        As for :func:`~o3d_spectral.evidence.fit.fit`.
    fixed : open3d.geometry.PointCloud
        The fixed cloud with normals, metres.
    ranked : list of Hypothesis
        The search's placed hypotheses, best first (at least one).
    fits : dict, optional
        :func:`~o3d_spectral.evidence.fit.fit`'s results
        (:class:`~o3d_spectral.evidence.fit.Fit`) by hypothesis key
        (:attr:`~o3d_spectral.search.placement.Hypothesis.key`), kept across calls on the
        same clouds: a hypothesis still among the best after the sweep is not polished
        again. Hypotheses without a key are keyed by their rank.
    workers : int or None
        Threads (all cores when None). On one, the rivals are polished only where the
        best fits; on more, the :data:`CANDIDATES` are polished side by side at once
        (each the same whatever the thread: the outcome does not change).

    Returns
    -------
    Confirmation
    """
    fits = {} if fits is None else fits
    candidates = ranked[:CANDIDATES]
    keys = [hypothesis.key or ("rank", i) for i, hypothesis in enumerate(candidates)]
    starts = {key: h.transformation(moving.centroid) for key, h in zip(keys, candidates,
                                                                        strict=True)}
    if resolved_workers(workers) > 1:
        missing = [key for key in starts if key not in fits]
        polished = thread_map(lambda key: fit(stepper, moving, fixed, starts[key]), missing,
                              workers)
        fits.update(zip(missing, polished, strict=True))

    def fitted(key: tuple) -> Fit:
        if key not in fits:
            fits[key] = fit(stepper, moving, fixed, starts[key])
        return fits[key]

    best = fitted(keys[0])
    rivals = []
    if best.share >= MIN_FIT:
        rivals = [other for other in map(fitted, keys[1:]) if distinct(other.pose, best.pose)]
    confirmed = best.share >= MIN_FIT and all(other.close <= best.close for other in rivals)
    runner_up = max((other.share for other in rivals), default=0.0)
    return Confirmation(best.pose, best.share, runner_up, confirmed)


def closer(placed: Fit, returned: Fit) -> bool:
    """Whether the best placed pose, polished (``placed``, the confirmation's), lies
    clearly closer to the fixed cloud than the pose the search returned when nothing was
    confirmed (``returned``, measured where it is: ``fit(..., polish=False)``): more of
    its points within :data:`~o3d_spectral.evidence.fit.CLOSE_DISTANCE`, by over
    :data:`CLOSER_MARGIN`. The climbs
    rank poses by the spectral score, which a view half hidden can mislead (a pose that
    matches what hides the object); the closeness measures the pose against the points.
    """
    return placed.close > returned.close + CLOSER_MARGIN
