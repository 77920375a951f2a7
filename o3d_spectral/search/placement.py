"""Candidates placed by phase correlation: the search's hypotheses, and what it keeps of them.

Each candidate rotation is placed by one phase correlation of the turned moving cloud's
voxel grid against the fixed one (:meth:`o3d_spectral.SpectralStepper.locate`'s, batched
over the candidates: :mod:`o3d_spectral.correlation`) and scored by that correlation's
peak height: how well the turned grid matches under any shift.
Between two scans the candidates are first ranked on a coarser grid and only the best are
placed. :class:`Placements` keeps every coarse score and placement of one registration by
candidate key, so that a rotation ranked again (after the sweep, or near a place whose
search covers the whole grid) is not placed again.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..correlation import BatchedCorrelation
from ..law.loop import Climb
from ..law.stepper import MovingCloud, SpectralStepper
from ..spectra import so3
from ..spectra.constants import COARSE_FACTOR
from ..spectra.grid import Box
from .candidates import Candidate, placed_peaks, span_factor, turned_cloud
from .constants import PLACEMENT_SPAN

__all__ = ["Hypothesis", "Placements", "place", "placed_in", "placement_factor", "best_first",
           "places", "PLACEMENT_SPAN"]


@dataclass(frozen=True, eq=False)
class Hypothesis:
    """A candidate rotation placed by phase correlation.

    The moving cloud fits the fixed one at ``x -> rotation (x - c) + centre`` (``c``: its
    centroid).

    Attributes
    ----------
    rotation : ndarray, shape (3, 3)
        The rotation, about the moving cloud's centroid.
    centre : ndarray, shape (3,)
        Where the phase correlation puts the turned cloud's centroid, metres.
    translation_peak : float
        Height of that phase-correlation peak in [0, 1]: the hypothesis' score.
    cost_translation : float
        ``J_t`` of the turned cloud before that shift, in [0, 2].
    key : tuple
        The candidate's key and the block of the fixed grid searched
        (:class:`Placements`); empty for a pose placed outside the search's bookkeeping.
    """

    rotation: NDArray[np.float64]
    centre: NDArray[np.float64]
    translation_peak: float
    cost_translation: float
    key: tuple = ()

    def climb(self, moving: MovingCloud, *, egi_scored: bool = True) -> Climb:
        """A climb of the law starting at this hypothesis (see :class:`Climb`)."""
        return Climb(moving.centroid, self.rotation, self.centre - moving.centroid,
                     predicted=self.centre, egi_scored=egi_scored)

    def transformation(self, centroid: NDArray[np.float64]) -> NDArray[np.float64]:
        """The hypothesis as a 4x4 rigid transform of a moving cloud whose centroid is
        ``centroid`` (3,), metres."""
        return so3.about_pivot(self.rotation, self.centre - centroid, centroid)


@dataclass
class Placements:
    """What one registration measured of its candidates, by candidate key.

    Attributes
    ----------
    coarse : dict
        Candidate key -> peak height on the coarse ranking grid (two scans).
    placed : dict
        (candidate key, grid factor, searched block's offset or None for the whole grid)
        -> :class:`Hypothesis`.
    """

    coarse: dict[tuple, float] = field(default_factory=dict)
    placed: dict[tuple, Hypothesis] = field(default_factory=dict)


def place(
    stepper: SpectralStepper, moving: MovingCloud, candidates: list[Candidate],
    placements: Placements, *, around: ArrayLike | None = None, two_scans: bool = False,
    coarse_placements: int = 0, workers: int | None = 1,
) -> list[Hypothesis]:
    """``candidates`` placed by phase correlation near ``around`` (metres; anywhere when
    None), highest placed peak first.

    Between ``two_scans`` and placed anywhere: on a grid where the moving cloud spans at
    most :data:`PLACEMENT_SPAN` cells, and only the ``coarse_placements`` (when over 0)
    that place best on one :data:`~o3d_spectral.spectra.target_grid.COARSE_FACTOR` times
    as coarse are kept. What is in ``placements`` is not measured again; what is measured
    is added to it, in one batched correlation on ``workers`` threads:
    :meth:`o3d_spectral.SpectralStepper.locate`'s place, peak and ``J_t`` for each, to
    single precision's rounding.
    """
    factor = 1.0
    if around is None:
        factor = placement_factor(stepper.voxel_size, moving.radius, two_scans=two_scans)
        if two_scans and 0 < coarse_placements < len(candidates):
            candidates = _coarse_best(stepper, moving, candidates, placements,
                                      COARSE_FACTOR * factor, coarse_placements, workers)

    grid = stepper.grid.coarsened(factor)
    block = grid.search_box(moving.radius, around)  # the block locate searches
    searched = (factor, None if block is grid.box else tuple(block.offset))

    def key_of(candidate: Candidate) -> tuple:
        return (candidate.key, *searched)

    new = [c for c in candidates if key_of(c) not in placements.placed]
    if new:
        rotations = np.stack([c.rotation for c in new])
        found = placed_in(stepper, moving, rotations, factor, block, workers)
        for candidate, (centre, peak, cost) in zip(new, found, strict=True):
            placements.placed[key_of(candidate)] = Hypothesis(
                candidate.rotation, centre, peak, cost, key_of(candidate))
    return best_first([placements.placed[key_of(c)] for c in candidates])


def placed_in(
    stepper: SpectralStepper, moving: MovingCloud, rotations: NDArray[np.float64],
    factor: float, block: Box, workers: int | None,
) -> list[tuple[NDArray[np.float64], float, float]]:
    """:meth:`o3d_spectral.SpectralStepper.locate`'s centre (metres), peak height and
    ``J_t`` for the moving cloud turned by each of ``rotations`` (K, 3, 3), correlated
    with the ``block`` of the fixed grid of ``factor`` voxels in one batched correlation
    (:class:`o3d_spectral.correlation.BatchedCorrelation`) on ``workers`` threads. The
    block's spectrum is the fixed grid's cached one
    (:meth:`o3d_spectral.spectra.target_grid.TargetGrid.spectrum`), shared with the
    correlations against that block that follow."""
    grid = stepper.grid.coarsened(factor)
    box = grid.moving_box(moving.radius, moving.centroid)
    correlation = BatchedCorrelation(
        grid.block(block), box.shape, shape=grid.fft_shape(block, box, moving.radius),
        sigma=grid.peak_width, backend=stepper.backend,
        searched=grid.searched(block, box, moving.radius), overlap=grid.values,
        overlap_at=box.offset - grid.box.offset, spectrum=grid.spectrum(block, box, moving.radius),
    )
    peaks = correlation.peaks(turned_cloud(stepper, moving, factor), rotations, workers)
    shifts = block.offset - box.offset + peaks.shifts + peaks.fractions  # voxels
    centres = moving.centroid + shifts * grid.voxel_size
    return [(centres[i], float(peaks.heights[i]), 1.0 - float(peaks.overlaps[i]))
            for i in range(len(rotations))]


def placement_factor(voxel_size: float, radius: float, *, two_scans: bool) -> float:
    """The grid (voxels) on which :func:`place` places candidates anywhere for a moving
    cloud of ``radius`` (metres): between ``two_scans``, one where it spans at most
    :data:`PLACEMENT_SPAN` cells; the voxel itself otherwise."""
    return span_factor(voxel_size, radius, PLACEMENT_SPAN) if two_scans else 1.0


def _coarse_best(
    stepper: SpectralStepper, moving: MovingCloud, candidates: list[Candidate],
    placements: Placements, factor: float, count: int, workers: int | None,
) -> list[Candidate]:
    """The ``count`` candidates that place best on a grid of ``factor`` voxels, in their
    order in ``candidates``."""
    new = [c for c in candidates if c.key not in placements.coarse]
    scores = placed_peaks(stepper, moving, [c.rotation for c in new], factor, workers)
    for candidate, score in zip(new, scores, strict=True):
        placements.coarse[candidate.key] = score
    scores = np.array([placements.coarse[c.key] for c in candidates])
    best = np.argsort(-scores, kind="stable")[:count]
    return [candidates[i] for i in np.sort(best)]


def best_first(found: list[Hypothesis]) -> list[Hypothesis]:
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
