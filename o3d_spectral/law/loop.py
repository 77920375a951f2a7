"""The control law's loop (paper, eq. control_law and Algorithm 1) on one moving cloud.

A :class:`Climb` is one run of the law: its pose ``x -> R (x - c) + c + T`` about the
moving cloud's centroid ``c``, its EGI smoothing level and its history. :func:`climb`
iterates :meth:`o3d_spectral.SpectralStepper.evaluate`: ``T <- T + lambda_t grad_glob T``,
``R <- R exp(lambda_r hat(step))``, until both full corrections are below their
tolerances at the finest smoothing level.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ..spectra import so3
from .stepper import Evaluation, MovingCloud, SpectralStepper

__all__ = ["IterationRecord", "Climb", "climb", "pose_score"]


@dataclass(frozen=True)
class IterationRecord:
    """One iteration of the control law (the data of the paper's Fig. 2).

    Attributes
    ----------
    iteration : int
    transformation : ndarray, shape (4, 4)
        Source-to-target estimate at the start of the iteration (``init`` included).
    rotation : ndarray, shape (3, 3)
        The law's ``R`` at the start of the iteration (about the source's centroid).
    translation : ndarray, shape (3,)
        The law's ``T`` at the start of the iteration, metres.
    cost_translation, cost_rotation : float
        ``J_t``, ``J_r`` at that pose.
    translation_gradient_norm : float
        ``||grad_glob T||``, metres.
    rotation_gradient_norm : float
        Norm of the rotation step, radians (the paper's ``||grad C_r||`` over the
        correlation's curvature).
    correlation : float
        ``C_r(R)``.
    translation_peak : float
        Phase-correlation peak height in [0, 1].
    time : float
        Seconds since the registration started, at the end of the iteration.
    centre : ndarray, shape (3,)
        Where the phase correlation put the source's centroid at this iteration
        (metres, target frame, after ``init``).
    """

    iteration: int
    transformation: NDArray[np.float64]
    rotation: NDArray[np.float64]
    translation: NDArray[np.float64]
    cost_translation: float
    cost_rotation: float
    translation_gradient_norm: float
    rotation_gradient_norm: float
    correlation: float
    translation_peak: float
    time: float
    centre: NDArray[np.float64]


def pose_score(peak: float, correlation: float | None) -> float:
    """How well a pose fits: its phase-correlation peak height (how well the voxels match)
    times its EGI correlation ``4 pi C_r`` (1 for identical EGIs): a pose must match both
    the shape and the normals. The peak alone when ``correlation`` is None (two views,
    whose EGIs differ by what each sensor sees even at the true pose)."""
    return peak if correlation is None else peak * 4.0 * np.pi * correlation


@dataclass
class Climb:
    """One run of the control law.

    Attributes
    ----------
    centroid : ndarray, shape (3,)
        The moving cloud's centroid ``c``, metres (the rotation's pivot).
    R : ndarray, shape (3, 3)
        Current rotation about ``c``.
    T : ndarray, shape (3,)
        Current translation, metres.
    level : int
        EGI smoothing level.
    history : list of IterationRecord
    converged : bool
    predicted : ndarray, shape (3,) or None
        Where the last phase correlation put the centroid (metres); None before the first.
    scores : list of float
        :func:`pose_score` of the iterates scored so far (:meth:`best_iterate`).
    egi_scored : bool
        Whether the EGI correlation counts in the score (not for two views:
        :class:`o3d_spectral.search.situation.Kind`).
    """

    centroid: NDArray[np.float64]
    R: NDArray[np.float64] = field(default_factory=lambda: np.eye(3))
    T: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    level: int = 0
    history: list[IterationRecord] = field(default_factory=list)
    converged: bool = False
    predicted: NDArray[np.float64] | None = None
    scores: list[float] = field(default_factory=list)
    egi_scored: bool = True

    def matrix(self) -> NDArray[np.float64]:
        """The current pose as a 4x4 rigid transformation."""
        return so3.about_pivot(self.R, self.T, self.centroid)

    @classmethod
    def at(cls, pose: NDArray[np.float64], centroid: NDArray[np.float64]) -> Climb:
        """A climb starting at ``pose`` (4, 4) of the cloud whose centroid is ``centroid``
        (3,, metres): the inverse of :meth:`matrix`."""
        R = np.array(pose[:3, :3], dtype=np.float64)
        return cls(centroid, R, R @ centroid + pose[:3, 3] - centroid)

    def best_iterate(self) -> tuple[float, NDArray[np.float64], IterationRecord]:
        """The iterate that scores best (:func:`pose_score`; the first of equals), with
        its pose (4, 4; before ``init``): its rotation, and its centroid where its phase
        correlation put it.

        The law ascends ``C_r`` alone on EGIs that part of either cloud is missing from;
        the score also weighs where the voxels match, and on partial views it can fall as
        the law climbs away from a pose it started at.
        """
        for record in self.history[len(self.scores) :]:
            correlation = record.correlation if self.egi_scored else None
            self.scores.append(pose_score(record.translation_peak, correlation))
        k = int(np.argmax(self.scores))
        record = self.history[k]
        pose = so3.about_pivot(record.rotation, record.centre - self.centroid, self.centroid)
        return self.scores[k], pose, record


def climb(
    stepper: SpectralStepper,
    moving: MovingCloud,
    state: Climb,
    iterations: int,
    tolerance: tuple[float, float],
    init: NDArray[np.float64],
    start: float,
) -> None:
    """Apply the control law (eq. control_law) to ``state`` up to ``iterations`` times.

    Parameters
    ----------
    stepper : SpectralStepper
        The fixed cloud's spectra the law climbs against.
    moving : MovingCloud
    state : Climb
        Updated in place: pose, level, history, ``converged``.
    iterations : int
    tolerance : (float, float)
        Translation (metres) and rotation (radians) tolerances at the finest level.
    init : ndarray, shape (4, 4)
        Transformation applied to the source before ``moving`` was prepared (recorded in
        the history's transformations).
    start : float
        ``time.perf_counter()`` at the start of the registration.
    """
    for _ in range(iterations):
        if state.converged:
            return
        evaluation = stepper.evaluate(
            moving, state.R, state.T, level=state.level, around=state.predicted
        )
        state.predicted = moving.centroid + state.T + evaluation.translation
        state.history.append(_record(state, evaluation, init, start))
        level = stepper.next_level(state.level, evaluation)
        if level == state.level == stepper.levels - 1 and evaluation.within(tolerance):
            state.converged = True
            return
        state.level = level
        delta_rotation, delta_translation = stepper.increments(evaluation)
        state.T = state.T + delta_translation
        state.R = so3.project_to_rotation(state.R @ delta_rotation)


def _record(
    state: Climb, evaluation: Evaluation, init: NDArray[np.float64], start: float
) -> IterationRecord:
    """The record of the iteration ``evaluation`` was made at."""
    return IterationRecord(
        iteration=len(state.history),
        transformation=state.matrix() @ init,
        rotation=state.R.copy(),
        translation=state.T.copy(),
        cost_translation=evaluation.cost_translation,
        cost_rotation=evaluation.cost_rotation,
        translation_gradient_norm=float(np.linalg.norm(evaluation.translation)),
        rotation_gradient_norm=float(np.linalg.norm(evaluation.rotation)),
        correlation=evaluation.correlation,
        translation_peak=evaluation.translation_peak,
        time=time.perf_counter() - start,
        centre=state.predicted.copy(),
    )
