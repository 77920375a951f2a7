"""Per-instance metrics of the evaluation harness, built on :mod:`o3d_spectral.symmetry`.

Translation errors are measured at the source's centroid (``Instance.source_center``):
where the estimate and the ground truth put the object, not the source frame's origin,
which can lie a metre away and would turn every rotation error into a translation error.
Rotation errors are in degrees, translation errors in metres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import open3d as o3d

from o3d_spectral.scenes import Instance
from o3d_spectral.symmetry import (
    rotation_error,
    symmetric_rotation_error,
    symmetric_translation_error,
    translation_error,
)

__all__ = ["SuccessCriteria", "convergence_curves", "instance_metrics", "registration_fit"]


@dataclass(frozen=True)
class SuccessCriteria:
    """When a registration counts as a success (both symmetry-aware errors within bounds).

    Attributes
    ----------
    max_rotation_deg : float
        Largest rotation error, degrees.
    max_translation_m : float
        Largest translation error at the object's centroid, metres.
    """

    max_rotation_deg: float = 5.0
    max_translation_m: float = 0.01

    def __post_init__(self) -> None:
        for name in ("max_rotation_deg", "max_translation_m"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be positive, got {getattr(self, name)}")


def instance_metrics(
    transformation: np.ndarray, instance: Instance, *, criteria: SuccessCriteria | None = None
) -> dict:
    """Errors of one estimate against the instance's ground truth.

    Parameters
    ----------
    transformation : ndarray, shape (4, 4)
        Estimated source-to-target transformation.
    instance : Instance
        The problem (``T_gt``, ``symmetry``, ``source_center`` are used).
    criteria : SuccessCriteria, optional
        Success thresholds; the defaults (5 degrees, 1 cm) when None.

    Returns
    -------
    dict
        ``rotation_error_deg``, ``translation_error_m`` (plain), ``rotation_error_sym_deg``,
        ``translation_error_sym_m`` (minimum over the object's symmetries, each
        separately), ``success`` (bool, on the symmetry-aware errors) and the paper's
        Table 1 terms ``squared_translation_error_m2`` (m^2) and
        ``squared_rotation_error_rad2`` (rad^2), also symmetry-aware.
    """
    criteria = criteria or SuccessCriteria()
    T_gt, center = instance.T_gt, instance.source_center
    rotation_sym = symmetric_rotation_error(transformation, T_gt, instance.symmetry)
    translation_sym = symmetric_translation_error(
        transformation, T_gt, instance.symmetry, center=center
    )
    return {
        "rotation_error_deg": rotation_error(transformation, T_gt),
        "translation_error_m": translation_error(transformation, T_gt, center=center),
        "rotation_error_sym_deg": rotation_sym,
        "translation_error_sym_m": translation_sym,
        "success": bool(
            rotation_sym <= criteria.max_rotation_deg
            and translation_sym <= criteria.max_translation_m
        ),
        "squared_translation_error_m2": translation_sym**2,
        "squared_rotation_error_rad2": np.deg2rad(rotation_sym) ** 2,
    }


def convergence_curves(trajectory: np.ndarray, instance: Instance) -> tuple[list, list]:
    """Symmetry-aware errors of each iterate (the data of the paper's Fig. 2 and 4).

    Parameters
    ----------
    trajectory : ndarray, shape (K, 4, 4)
        Source-to-target estimate at the start of each iteration.
    instance : Instance

    Returns
    -------
    rotation_deg, translation_m : list of float, length K
        Rotation error (degrees) and translation error at the object's centroid (m).
    """
    trajectory = np.asarray(trajectory, dtype=np.float64)
    if trajectory.ndim != 3 or trajectory.shape[1:] != (4, 4):
        raise ValueError(f"trajectory must have shape (K, 4, 4), got {trajectory.shape}")
    T_gt, symmetry, center = instance.T_gt, instance.symmetry, instance.source_center
    rotation = [symmetric_rotation_error(T, T_gt, symmetry) for T in trajectory]
    translation = [
        symmetric_translation_error(T, T_gt, symmetry, center=center) for T in trajectory
    ]
    return rotation, translation


def registration_fit(
    transformation: np.ndarray, instance: Instance, *, distance: float
) -> tuple[float, float]:
    """Open3D's ``fitness`` and ``inlier_rmse`` (m) of an estimate, measured the same way
    for every method: ``evaluate_registration`` on the full clouds at ``distance`` (m)."""
    if not distance > 0:
        raise ValueError(f"distance must be positive, got {distance}")
    result = o3d.pipelines.registration.evaluate_registration(
        instance.source, instance.target, distance, np.asarray(transformation, dtype=np.float64)
    )
    return float(result.fitness), float(result.inlier_rmse)
