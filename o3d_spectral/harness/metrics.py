"""Per-instance metrics of the evaluation harness, built on :mod:`o3d_spectral.harness.errors`.

Translation errors are measured at the source's centroid (``Instance.source_center``):
where the estimate and the ground truth put the object, not the source frame's origin,
which can lie a metre away and would turn every rotation error into a translation error.
Rotation errors are in degrees, translation errors in metres.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cache

import numpy as np
import open3d as o3d
from scipy.spatial import cKDTree

from o3d_spectral.harness.constants import OBSERVATION_TOLERANCE
from o3d_spectral.harness.errors import (
    rotation_error,
    symmetric_rotation_error,
    symmetric_translation_error,
    translation_error,
)
from o3d_spectral.synthetic import models
from o3d_spectral.synthetic.instance import Instance

__all__ = [
    "OBSERVATION_TOLERANCE",
    "ObservationFit",
    "SuccessCriteria",
    "convergence_curves",
    "indistinguishable",
    "instance_metrics",
    "instance_score",
    "observation_fit",
    "registration_fit",
]


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


def instance_score(instance: Instance) -> Callable[[np.ndarray], tuple[float, float, bool]]:
    """``(T) -> (rotation error deg, translation error m, success)`` of an estimate ``T``
    (4, 4) of ``instance``, symmetry-aware (:func:`instance_metrics`)."""

    def score(transformation: np.ndarray) -> tuple[float, float, bool]:
        m = instance_metrics(transformation, instance)
        return m["rotation_error_sym_deg"], m["translation_error_sym_m"], m["success"]

    return score


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


@cache
def _model_surface(name: str) -> tuple[o3d.t.geometry.RaycastingScene, np.ndarray, float]:
    """Distance queries to a bundled mesh in its own frame, and its bounding ball (centre,
    metres; radius, metres); built once per process."""
    mesh = models.load_model(name)
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(mesh))
    vertices = np.asarray(mesh.vertices)
    centre = 0.5 * (vertices.min(axis=0) + vertices.max(axis=0))
    return scene, centre, float(np.max(np.linalg.norm(vertices - centre, axis=1)))


@dataclass(frozen=True)
class ObservationFit:
    """How well a pose of the object explains the observed cloud (:func:`observation_fit`).

    Attributes
    ----------
    explained : int
        Observed (target) points within the tolerance of the posed model's surface.
    matched : float
        Share of the posed model's points that face the sensor (all of them for a target
        that is not a view) with an observed point within the tolerance.
    """

    explained: int
    matched: float


def observation_fit(
    transformation: np.ndarray, instance: Instance, *, tolerance: float = OBSERVATION_TOLERANCE
) -> ObservationFit:
    """What the observation says of a pose: the two sides of how the posed model and the
    observed points cover each other, measured on the mesh and the full clouds.

    Parameters
    ----------
    transformation : ndarray, shape (4, 4)
        Source-to-target pose.
    instance : Instance
        Its ``target`` is the observation (a scan in its sensor's frame, sensor at the
        origin, when ``metadata`` has a ``"view"``); its mesh is the bundled model.
    tolerance : float
        Metres.
    """
    pose = np.asarray(transformation, dtype=np.float64) @ instance.source_from_model
    surface, centre, radius = _model_surface(instance.object)
    observed = np.asarray(instance.target.points)
    in_model = (observed - pose[:3, 3]) @ pose[:3, :3]  # pose^-1 applied to the points
    near = np.linalg.norm(in_model - centre, axis=1) <= radius + tolerance  # the others miss
    query = o3d.core.Tensor(in_model[near].astype(np.float32))
    distance = surface.compute_distance(query).numpy()
    T = np.asarray(transformation, dtype=np.float64)
    points = np.asarray(instance.source.points) @ T[:3, :3].T + T[:3, 3]
    if "view" in instance.metadata:  # the sensor at the origin sees the faces turned to it
        normals = np.asarray(instance.source.normals) @ T[:3, :3].T
        points = points[np.einsum("ij,ij->i", normals, -points) > 0.0]
    gaps, _ = cKDTree(observed[near]).query(points, distance_upper_bound=tolerance)
    matched = float(np.mean(np.isfinite(gaps))) if len(points) else 0.0
    return ObservationFit(int(np.sum(distance <= tolerance)), matched)


def indistinguishable(
    transformation: np.ndarray, instance: Instance, *, slack: float = 0.01
) -> bool:
    """Whether a pose fits the observation as well as the ground truth does.

    True when the posed model explains at least ``1 - slack`` times as many observed
    points as the truth does and at least the truth's share of its sensor-facing points,
    less ``slack``, are matched (:func:`observation_fit`). A wrong pose for which this
    holds is one that no ranking of poses by how well they fit the observed points can be
    relied on to reject: the view, not the method, leaves it open (an object's hidden
    side, a look-alike place in a scene). Symmetries of the object are not involved: a
    pose equal to the truth up to one of them is a success.
    """
    truth = observation_fit(instance.T_gt, instance)
    estimate = observation_fit(transformation, instance)
    return bool(
        estimate.explained >= (1.0 - slack) * truth.explained
        and estimate.matched >= truth.matched - slack
    )
