"""Rotation candidates for the global search, each named by where it came from.

- :func:`egi_candidates`: the highest peaks of the rotation correlation of the two
  clouds' Extended Gaussian Images over the whole of SO(3), by SO(3) Fourier transforms
  (:meth:`o3d_spectral.SpectralStepper.rotation_grid`);
- :func:`shell_candidates` (two scans): the peaks of the correlation of the voxel grids'
  Fourier magnitudes on spherical shells, which no translation changes
  (:mod:`o3d_spectral.spectra.shells`);
- :func:`swept_candidates` (two scans): the rotations of an even sweep of SO(3) that
  place best by a coarse phase correlation.

A candidate's :attr:`Candidate.key` names its rotation on its own grid (the Euler grid's
index, the sweep's position), so that the search can keep what it measured of a rotation
(:mod:`o3d_spectral.search.placement`) without comparing matrices.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from ..correlation import BatchedCorrelation, TurnedCloud
from ..io.cloud import MIN_POINTS
from ..law.stepper import MovingCloud, SpectralStepper
from ..spectra import so3
from ..spectra.shells import SHELL_BANDWIDTH, shell_coefficients, shell_voxel
from ..spectra.so3fft import CorrelationGrid, correlation_grid, peak_indices
from .constants import (
    SWEEP_FACTOR,
    SWEEP_PLACEMENTS,
    SWEEP_PRESELECT_FACTOR,
    SWEEP_PRESELECTED,
    SWEEP_SENSOR_ANGLE,
    SWEEP_SPAN,
)
from .options import GlobalSearchOption

__all__ = [
    "Candidate", "egi_candidates", "shell_candidates", "swept_candidates", "span_factor",
    "placed_peaks", "turned_correlation", "turned_cloud", "SWEEP_FACTOR", "SWEEP_SPAN",
    "SWEEP_PLACEMENTS", "SWEEP_SENSOR_ANGLE", "SWEEP_PRESELECT_FACTOR", "SWEEP_PRESELECTED",
]


class Candidate(NamedTuple):
    """A rotation to place.

    Attributes
    ----------
    key : tuple
        Where it came from and its index there (``("egi", (j, a, c))``, ``("shell",
        (j, a, c))``, ``("sweep", i)``): equal keys name the same rotation within one
        registration.
    rotation : ndarray, shape (3, 3)
        About the moving cloud's centroid.
    value : float
        Its score where it came from (a correlation value, a coarse peak height).
    """

    key: tuple
    rotation: NDArray[np.float64]
    value: float


def _grid_peaks(grid: CorrelationGrid, source: str, count: int) -> list[Candidate]:
    """The ``count`` highest peaks of ``grid`` as candidates named ``source``."""
    return [Candidate((source, index), grid.rotation(index), value)
            for index, value in peak_indices(grid, count=count)]


def egi_candidates(
    stepper: SpectralStepper, moving: MovingCloud, search: GlobalSearchOption
) -> list[Candidate]:
    """The ``search.hypotheses`` highest peaks of ``C_r`` over SO(3), highest first
    (:meth:`o3d_spectral.SpectralStepper.rotation_grid`, on ``search.samples`` Euler
    samples: a focused stepper's peaks share the keys of the whole EGI's)."""
    grid = stepper.rotation_grid(
        moving, search.samples(stepper.option.bandwidth), visibility=search.search_visibility
    )
    return _grid_peaks(grid, "egi", search.hypotheses)


def shell_candidates(
    target_points: NDArray[np.float64], moving_points: NDArray[np.float64], count: int
) -> list[Candidate]:
    """The ``count`` highest peaks over SO(3) of the correlation of the two clouds'
    spectra on spherical shells (:mod:`o3d_spectral.spectra.shells`), highest first;
    points (N, 3) in metres."""
    voxel = shell_voxel(target_points, moving_points)
    grid = correlation_grid(
        shell_coefficients(moving_points, voxel), shell_coefficients(target_points, voxel),
        n_alpha=2 * SHELL_BANDWIDTH, n_beta=2 * SHELL_BANDWIDTH,
    )
    return _grid_peaks(grid, "shell", count)


def span_factor(voxel_size: float, radius: float, span: float) -> float:
    """The grid factor (voxels, at least 1, in steps of half a voxel so that clouds of
    about one size share their coarse grids) at which a moving cloud of ``radius``
    (metres) spans at most ``span`` cells across (:meth:`o3d_spectral.SpectralStepper.locate`'s
    ``factor``): searches that place many rotations keep their cost bounded whatever the
    clouds' size."""
    return max(1.0, np.ceil(4.0 * radius / (span * voxel_size)) / 2.0)


def swept_candidates(
    stepper: SpectralStepper, moving: MovingCloud, count: int, workers: int | None = 1
) -> list[Candidate]:
    """For two scans: the :data:`SWEEP_PLACEMENTS` rotations, of ``count`` spread evenly
    over SO(3), that place best by phase correlation on a coarse grid (value: the peak
    height), best first.

    Of the ``count`` rotations of :func:`o3d_spectral.spectra.so3.uniform_rotations`, those
    that turn the moving view's sensor direction within :data:`SWEEP_SENSOR_ANGLE` of the
    fixed view's are ranked on a grid :data:`SWEEP_PRESELECT_FACTOR` times coarser than
    the sweep's own of :data:`SWEEP_FACTOR` voxels (coarser for a moving cloud over
    :data:`SWEEP_SPAN` of those across), and the :data:`SWEEP_PRESELECTED` best are placed
    on the sweep's grid (coarse to fine, as the placements are ranked), on ``workers``
    threads. Two scans far
    enough apart share too little of their normals for the EGI's peaks to hold their
    rotation; the peak of a phase correlation, which compares the shapes themselves, is
    highest there.
    """
    rotations = so3.uniform_rotations(count)
    toward = rotations @ moving.reading.view @ stepper.target_reading.view
    kept = np.flatnonzero(toward >= np.cos(SWEEP_SENSOR_ANGLE))
    rotations = rotations[kept]
    factor = max(SWEEP_FACTOR, span_factor(stepper.voxel_size, moving.radius, SWEEP_SPAN))
    preselected = np.arange(len(rotations))
    if len(rotations) > SWEEP_PRESELECTED:
        coarse = placed_peaks(stepper, moving, rotations, SWEEP_PRESELECT_FACTOR * factor,
                              workers)
        preselected = np.sort(np.argsort(-coarse, kind="stable")[:SWEEP_PRESELECTED])
    scores = np.full(len(rotations), -np.inf)
    scores[preselected] = placed_peaks(stepper, moving, rotations[preselected], factor, workers)
    best = np.argsort(-scores, kind="stable")[:SWEEP_PLACEMENTS]
    return [Candidate(("sweep", int(kept[i])), rotations[i], float(scores[i])) for i in best]


def placed_peaks(
    stepper: SpectralStepper, moving: MovingCloud, rotations: Iterable[NDArray[np.float64]],
    factor: float = 1.0, workers: int | None = 1,
) -> NDArray[np.float64]:
    """The phase-correlation peak heights of the moving cloud turned by each rotation
    (3, 3) about its centroid and placed anywhere on a grid of ``factor`` voxels:
    :meth:`o3d_spectral.SpectralStepper.locate`'s for each, batched
    (:func:`turned_correlation`), the batches on ``workers`` threads (the same heights
    whatever the threads)."""
    rotations = np.asarray(list(rotations), dtype=np.float64).reshape(-1, 3, 3)
    if not len(rotations):
        return np.zeros(0)
    correlation, cloud = turned_correlation(stepper, moving, factor)
    return correlation.peaks(cloud, rotations, workers).heights


def turned_correlation(
    stepper: SpectralStepper, moving: MovingCloud, factor: float = 1.0,
) -> tuple[BatchedCorrelation, TurnedCloud]:
    """The phase correlation of the moving cloud turned about its centroid against the
    whole fixed grid of ``factor`` voxels, batched over rotations
    (:class:`o3d_spectral.correlation.BatchedCorrelation`, on the stepper's backend, on
    its ``device``), and the moving cloud as it turns it (:func:`turned_cloud`):
    :meth:`o3d_spectral.SpectralStepper.locate`'s peak height for each rotation (to single
    precision's rounding)."""
    grid = stepper.grid.coarsened(factor)
    box = grid.moving_box(moving.radius, moving.centroid)
    correlation = BatchedCorrelation(
        grid.values, box.shape, shape=grid.fft_shape(grid.box, box, moving.radius),
        sigma=grid.peak_width, backend=stepper.backend,
    )
    return correlation, turned_cloud(stepper, moving, factor)


def turned_cloud(stepper: SpectralStepper, moving: MovingCloud, factor: float) -> TurnedCloud:
    """The moving cloud as a batched correlation on the fixed grid of ``factor`` voxels
    turns it about its centroid, on its moving grid
    (:meth:`~o3d_spectral.spectra.target_grid.TargetGrid.moving_box`): culled as
    :meth:`o3d_spectral.SpectralStepper.visible` culls."""
    grid = stepper.grid.coarsened(factor)
    corner = grid.moving_box(moving.radius, moving.centroid).corner
    culled, voxel = stepper.sees(moving), grid.voxel_size
    return TurnedCloud(
        (moving.points - moving.centroid) / voxel, (moving.centroid - corner) / voxel,
        normals=moving.point_normals if culled else None,
        viewpoint=(stepper.viewpoint - corner) / voxel if culled else None,
        two_sided=moving.reading.two_sided, min_facing=MIN_POINTS, weighting=grid.weighting,
    )
