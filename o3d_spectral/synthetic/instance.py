"""What a registration instance is, and the settings of the scene generator that makes it.

The conditions and the presentation pose are described in :mod:`.scenes`, which builds
the instances; ``docs/suites.md`` describes them in full.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import open3d as o3d

from o3d_spectral.synthetic.constants import BACKGROUND, MAX_TRIES
from o3d_spectral.synthetic.models import model_names
from o3d_spectral.synthetic.sensor import CameraIntrinsics, DepthNoise
from o3d_spectral.synthetic.symmetry import Symmetry, model_symmetry

__all__ = ["BACKGROUND", "CONDITIONS", "MAX_TRIES", "Instance", "SceneOptions"]

CONDITIONS: tuple[str, ...] = ("full", "partial", "occluded", "cluttered")


_MODEL_SEED = 20240601  # fixed: a model's source cloud is the same in every suite


@dataclass(frozen=True)
class SceneOptions:
    """Settings of the scene generator (units: metres, radians).

    Parameters
    ----------
    intrinsics : CameraIntrinsics
        The virtual camera (default 640x480, 60 degrees wide).
    noise : DepthNoise
        Sensor model of the scans.
    source_points : int
        Points of the source (Poisson-disk samples of the model mesh).
    full_noise_sigma : float
        Standard deviation (m) of the isotropic Gaussian noise on the ``full`` target.
    angle_range : (float, float) or None
        Initial rotation angle range (radians) in [0, pi]; None draws uniformly over SO(3).
    max_offset : float
        Upper bound (m) of the initial displacement of the object centroid.
    distance_range : (float, float)
        Camera-to-object distance (m) in ``partial`` and ``occluded``.
    occlusion_range : (float, float)
        Range of the requested occlusion fraction in ``occluded``.
    clutter_objects : (int, int)
        Inclusive range of the number of objects on the table in ``cluttered``.
    min_visible : float
        ``cluttered``: least share of the chosen object's pixels that other objects may
        leave visible (``1 - occlusion``).
    """

    intrinsics: CameraIntrinsics = field(default_factory=CameraIntrinsics)
    noise: DepthNoise = field(default_factory=DepthNoise)
    source_points: int = 3000
    full_noise_sigma: float = 0.001
    angle_range: tuple[float, float] | None = None
    max_offset: float = 0.1
    distance_range: tuple[float, float] = (0.4, 1.0)
    occlusion_range: tuple[float, float] = (0.2, 0.7)
    clutter_objects: tuple[int, int] = (3, 8)
    min_visible: float = 0.3

    def __post_init__(self) -> None:
        if self.source_points < 100:
            raise ValueError(f"source_points must be >= 100, got {self.source_points}")
        if self.angle_range is not None:
            lo, hi = self.angle_range
            if not 0 <= lo <= hi <= np.pi:
                raise ValueError(
                    f"angle_range must satisfy 0 <= min <= max <= pi (radians), got "
                    f"{self.angle_range}"
                )
        if self.max_offset < 0:
            raise ValueError(f"max_offset must be >= 0 m, got {self.max_offset}")
        if not 0 < self.distance_range[0] <= self.distance_range[1]:
            raise ValueError(f"distance_range must be 0 < min <= max, got {self.distance_range}")
        if not 0 <= self.occlusion_range[0] <= self.occlusion_range[1] < 1:
            raise ValueError(
                f"occlusion_range must satisfy 0 <= min <= max < 1, got {self.occlusion_range}"
            )
        if not 1 <= self.clutter_objects[0] <= self.clutter_objects[1] <= len(model_names()):
            raise ValueError(f"clutter_objects must be 1 <= min <= max, got {self.clutter_objects}")
        if not 0 < self.min_visible <= 1:
            raise ValueError(f"min_visible must be in (0, 1], got {self.min_visible}")


@dataclass
class Instance:
    """One registration problem.

    Attributes
    ----------
    source : open3d.geometry.PointCloud
        Object model points with outward normals, in the source frame (m).
    target : open3d.geometry.PointCloud
        The observation (m): for scans, camera frame with normals facing the camera.
    T_gt : ndarray, shape (4, 4), float64
        Ground truth, ``target ~ T_gt @ source`` on the object's points.
    target_labels : ndarray, shape (M,), int
        Per target point: index into ``metadata["scene_objects"]`` (0 is the object of
        ``source``), or -1 for table and occluder points.
    source_from_model : ndarray, shape (4, 4), float64
        Pose of the model mesh in the source frame: ``source = source_from_model @ mesh``.
    metadata : dict
        JSON-serialisable description (see ``docs/suites.md``).
    known_symmetry : Symmetry or None
        The object's symmetry group in the source frame, for an object that is not one of
        the bundled models (a BOP dataset's, from its ``models_info.json``; a scan pair's,
        trivial); None for a bundled model, whose group is found on its mesh.
    """

    source: o3d.geometry.PointCloud
    target: o3d.geometry.PointCloud
    T_gt: np.ndarray
    target_labels: np.ndarray
    source_from_model: np.ndarray
    metadata: dict
    known_symmetry: Symmetry | None = None

    @property
    def object(self) -> str:
        """Name of the model in ``source``."""
        return self.metadata["object"]

    @property
    def source_center(self) -> np.ndarray:
        """Centroid of the source points (m), shape (3,): where translation errors are
        measured (:func:`o3d_spectral.harness.errors.translation_error`'s ``center``)."""
        return np.asarray(self.source.points).mean(axis=0)

    @property
    def symmetry(self) -> Symmetry:
        """Symmetry group of the object, expressed in the source frame."""
        if self.known_symmetry is not None:
            return self.known_symmetry
        return model_symmetry(self.object).transformed(self.source_from_model)

