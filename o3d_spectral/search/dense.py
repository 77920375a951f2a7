"""The dense search: SO(3) sampled evenly, ranked at the voxel's own resolution.

The phase-correlation peak of the turned moving grid against the fixed one (its height:
how well the turned shapes agree under the best shift) is highest at the true rotation
when it is read on the voxel's own grid, and narrow there: about 10 degrees from the
truth it has fallen to half. On a grid three times coarser, many wrong rotations score
above the truth. :func:`dense_candidates` therefore samples SO(3) densely enough that
some rotation lies within a few degrees of any pose, and ranks them coarse to fine:

1. ``count`` rotations of :func:`o3d_spectral.spectra.so3.uniform_rotations` (between two
   scans, those that keep the two sensors within
   :data:`~o3d_spectral.search.candidates.SWEEP_SENSOR_ANGLE` of each other), ranked by
   their peak on a grid where the moving cloud spans about :data:`COARSE_SPAN` cells
   (3 voxels for a 0.2 m scan at 5 mm, the voxel itself for a smaller cloud);
2. the :data:`RERANKED` best ranked again on the placement's grid, the voxel's own
   (between two scans, for clouds up to
   :data:`~o3d_spectral.search.placement.PLACEMENT_SPAN` cells across:
   :func:`~o3d_spectral.search.placement.placement_factor`);
3. the :data:`REFINED` best that lie over :data:`START_SEPARATION` samples' spacings
   apart turned, on that grid, to where their peak is highest by a compass search (as
   :func:`o3d_spectral.search.ascent.peak_ascent` turns one pose, all the starts' trial
   turns correlated in one batch), from the samples' typical spacing down to
   :data:`FINEST_STEP`.

Every correlation is one of :class:`o3d_spectral.correlation.BatchedCorrelation`'s
batches, on every core the search's ``workers`` allow.

On the dragon scans 96-168 degrees apart (5 mm, 4608 rotations), the first rotation within
15 degrees of the truth ranked 1-9 on the 3-voxel grid, 1-3 after the voxel's, and the
highest refined peak lay 0.7-3.6 degrees from the truth on all seven pairs.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..correlation import BatchedCorrelation, TurnedCloud
from ..law.stepper import MovingCloud, SpectralStepper
from ..spectra import so3
from .candidates import (
    SWEEP_PLACEMENTS,
    SWEEP_SENSOR_ANGLE,
    Candidate,
    span_factor,
    turned_correlation,
)
from .constants import COARSE_SPAN, FINEST_STEP, REFINED, RERANKED, SPACING_1000, START_SEPARATION
from .placement import placement_factor

__all__ = [
    "dense_candidates", "dense_rotations", "compass", "COARSE_SPAN", "RERANKED", "REFINED",
    "START_SEPARATION", "FINEST_STEP",
]


def dense_rotations(
    stepper: SpectralStepper, moving: MovingCloud, count: int, *, two_scans: bool
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """The ``count`` even rotations the dense search ranks: their indices in
    :func:`o3d_spectral.spectra.so3.uniform_rotations` and the rotations (K, 3, 3);
    between ``two_scans``, only those that turn the moving view's sensor direction within
    :data:`~o3d_spectral.search.candidates.SWEEP_SENSOR_ANGLE` of the fixed view's."""
    rotations = so3.uniform_rotations(count)
    kept = np.arange(count)
    if two_scans:
        toward = rotations @ moving.reading.view @ stepper.target_reading.view
        kept = np.flatnonzero(toward >= np.cos(SWEEP_SENSOR_ANGLE))
    return kept, rotations[kept]


def dense_candidates(
    stepper: SpectralStepper, moving: MovingCloud, count: int, *, two_scans: bool,
    workers: int | None = 1,
) -> list[Candidate]:
    """The dense search's :data:`~o3d_spectral.search.candidates.SWEEP_PLACEMENTS`
    candidates, best first: the :data:`REFINED` rotations refined by the compass search
    (key ``("dense", i, "refined")``, ``i`` the start's index among the ``count``
    rotations) and the next best of the placement grid's ranking (``("dense", i)``);
    value: the peak height on the placement's grid (the module docstring)."""
    index, rotations = dense_rotations(stepper, moving, count, two_scans=two_scans)
    coarse = span_factor(stepper.voxel_size, moving.radius, COARSE_SPAN)
    fine = placement_factor(stepper.voxel_size, moving.radius, two_scans=two_scans)
    if coarse > fine and len(rotations) > RERANKED:
        correlation, cloud = turned_correlation(stepper, moving, coarse)
        heights = correlation.peaks(cloud, rotations, workers).heights
        best = np.sort(np.argsort(-heights, kind="stable")[:RERANKED])
        index, rotations = index[best], rotations[best]
    correlation, cloud = turned_correlation(stepper, moving, fine)
    heights = correlation.peaks(cloud, rotations, workers).heights
    order = np.argsort(-heights, kind="stable")
    spacing = _spacing(count)
    starts = _separated(rotations, order, START_SEPARATION * spacing, REFINED)
    refined, peaks = compass(correlation, cloud, rotations[starts], heights[starts],
                             first_step=spacing, workers=workers)
    found = [Candidate(("dense", int(index[i]), "refined"), R, float(h))
             for i, R, h in zip(starts, refined, peaks, strict=True)]
    found += [Candidate(("dense", int(index[i])), rotations[i], float(heights[i]))
              for i in order[: SWEEP_PLACEMENTS + len(starts)] if i not in starts]
    return sorted(found, key=lambda c: -c.value)[:SWEEP_PLACEMENTS]


def _separated(
    rotations: NDArray[np.float64], order: NDArray[np.int64], angle: float, count: int
) -> NDArray[np.int64]:
    """The first ``count`` of ``order`` (indices of ``rotations``) each over ``angle``
    (radians) from the ones taken before it."""
    taken: list[int] = []
    for i in order:
        if all(so3.rotation_angle(rotations[j].T @ rotations[i]) > angle for j in taken):
            taken.append(int(i))
            if len(taken) == count:
                break
    return np.array(taken, dtype=np.int64)


def _spacing(count: int) -> float:
    """The typical distance (radians) from a rotation to the nearest of ``count`` even
    ones (:data:`SPACING_1000`)."""
    return SPACING_1000 * (1000.0 / count) ** (1.0 / 3.0)


def compass(
    correlation: BatchedCorrelation, cloud: TurnedCloud, starts: NDArray[np.float64],
    heights: NDArray[np.float64], *, first_step: float, finest: float = FINEST_STEP,
    workers: int | None = 1,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Each of ``starts`` (K, 3, 3) turned to where its phase-correlation peak is highest,
    by a compass search (Kolda, Lewis and Torczon, SIAM Review 2003): turns of ``+-step``
    about each axis are tried, the best kept where it raises the peak, and the step
    halved where none does, from ``first_step`` down to ``finest`` (radians). The starts'
    trial turns are correlated together, one batch a round.

    Parameters
    ----------
    correlation : BatchedCorrelation
    cloud : TurnedCloud
    starts : ndarray, shape (K, 3, 3)
    heights : ndarray, shape (K,)
        The starts' peak heights on ``correlation``.
    first_step, finest : float
        Radians.
    workers : int or None

    Returns
    -------
    rotations : ndarray, shape (K, 3, 3)
    heights : ndarray, shape (K,)
        Each at least its start's.
    """
    rotations, heights = np.array(starts, dtype=np.float64), np.array(heights, dtype=np.float64)
    steps = np.full(len(rotations), float(first_step))
    turns = np.concatenate([np.eye(3), -np.eye(3)])
    while np.any(active := steps >= finest):
        who = np.flatnonzero(active)
        trials = np.stack([so3.exp(steps[k] * axis) @ rotations[k] for k in who for axis in turns])
        tried = correlation.peaks(cloud, trials, workers).heights.reshape(len(who), len(turns))
        for row, k in enumerate(who):
            best = int(np.argmax(tried[row]))
            if tried[row, best] > heights[k]:
                rotations[k], heights[k] = trials[row * len(turns) + best], tried[row, best]
            else:
                steps[k] /= 2.0
    return rotations, heights
