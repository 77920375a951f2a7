"""The static tabletop the camera looks at, the sensor, and the random start poses.

The scene is the scene suite's tabletop (:mod:`o3d_spectral.synthetic.tabletop`: a 0.8 x
0.6 m table, top at z = 0, with YCB objects resting on it without overlap, the first in the
table's central half and the others clustered near it). The sensor is the suites' depth
camera model (:mod:`o3d_spectral.synthetic.camera`: Open3D raycasting, the same
structured-light noise and quantisation) at a 320 x 240 resolution. The arm's base stands
beside the table at :data:`WORLD_FROM_BASE`; the robot itself is not rendered.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import open3d as o3d
from numpy.typing import NDArray

from ..spectra import so3
from ..synthetic.camera import look_at, scan_meshes
from ..synthetic.models import model_names
from ..synthetic.sampling import sample_surface
from ..synthetic.sensor import CameraIntrinsics, DepthNoise
from ..synthetic.tabletop import table_mesh, tabletop
from .constants import WORLD_FROM_BASE
from .robot import Arm

__all__ = [
    "WORLD_FROM_BASE",
    "Tabletop",
    "Sensor",
    "Start",
    "make_tabletop",
    "desired_pose",
    "sample_start",
]


_MAX_TRIES = 500
_ROLLS = np.linspace(-np.pi / 2, np.pi / 2, 91)  # candidate start rolls, radians


@dataclass(frozen=True)
class Tabletop:
    """A static scene, world frame (metres).

    Attributes
    ----------
    names : tuple of str
        Bundled models on the table; the first is the object of interest (the one the
        camera aims at, and whose visibility the start pose controls).
    meshes : tuple of open3d.geometry.TriangleMesh
        The table, then the objects in the order of ``names``.
    """

    names: tuple[str, ...]
    meshes: tuple[o3d.geometry.TriangleMesh, ...]

    @property
    def target_object(self) -> o3d.geometry.TriangleMesh:
        """Mesh of ``names[0]``."""
        return self.meshes[1]


def make_tabletop(rng: np.random.Generator, *, objects: tuple[int, int] = (3, 6)) -> Tabletop:
    """A random tabletop of ``objects[0]`` to ``objects[1]`` distinct YCB models.

    Parameters
    ----------
    rng : numpy.random.Generator
        Every random choice comes from it.
    objects : (int, int)
        Inclusive range of the number of models drawn (some may not fit on the table).
    """
    available = model_names()
    if not 1 <= objects[0] <= objects[1] <= len(available):
        raise ValueError(f"objects must satisfy 1 <= min <= max <= {len(available)}, got {objects}")
    count = int(rng.integers(objects[0], objects[1] + 1))
    chosen = [str(n) for n in rng.choice(available, size=count, replace=False)]
    names, _, meshes = tabletop(chosen, rng)
    return Tabletop(tuple(names), (table_mesh(), *meshes))


@dataclass(frozen=True)
class Sensor:
    """The eye-in-hand depth camera.

    Attributes
    ----------
    intrinsics : CameraIntrinsics
        320 x 240 pixels, 60 degrees wide: at 0.6 m a pixel spans 2 mm, four per 8 mm voxel,
        so the voxel grid is as full as at 640 x 480 while the cloud has a quarter of the
        points to prepare each cycle.
    noise : DepthNoise
        The scene suites' structured-light model.
    """

    intrinsics: CameraIntrinsics = field(
        default_factory=lambda: CameraIntrinsics.from_fov(width=320, height=240, fov=np.pi / 3)
    )
    noise: DepthNoise = field(default_factory=DepthNoise)

    def capture(
        self, scene: Tabletop, world_from_camera: NDArray, *, rng: np.random.Generator
    ) -> NDArray[np.float64]:
        """One noisy scan of the whole ``scene``: points and normals (N, 6), camera frame."""
        scan = scan_meshes(
            list(scene.meshes), self.intrinsics, world_from_camera, noise=self.noise, rng=rng
        )
        return np.hstack([scan.points, scan.normals])

    def visible_fraction(
        self, mesh: o3d.geometry.TriangleMesh, world_from_camera: NDArray, *, samples: int = 2000
    ) -> float:
        """Share of ``mesh``'s surface inside the field of view (occlusion ignored)."""
        points, _ = sample_surface(mesh, samples, rng=np.random.default_rng(0))
        camera = (points - world_from_camera[:3, 3]) @ world_from_camera[:3, :3]
        uv = self.intrinsics.project(camera)
        inside = (
            (camera[:, 2] > self.noise.min_depth)
            & np.all(uv >= -0.5, axis=1)
            & (uv[:, 0] < self.intrinsics.width - 0.5)
            & (uv[:, 1] < self.intrinsics.height - 0.5)
        )
        return float(inside.mean())


def desired_pose(
    arm: Arm,
    scene: Tabletop,
    rng: np.random.Generator,
    *,
    distance: tuple[float, float] = (0.5, 0.7),
    elevation: tuple[float, float] = (np.deg2rad(55.0), np.deg2rad(80.0)),
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """A reachable camera pose looking at the object of interest from the robot's side.

    The camera aims at the object's footprint centre from ``distance`` metres, at an
    ``elevation`` above the table (radians), from within 40 degrees of the direction of
    the robot's base, image up pointing away from the robot.

    Returns
    -------
    q : ndarray, shape (7,)
        Joint positions, radians (2 degrees or more inside every limit).
    world_from_camera : ndarray, shape (4, 4)
    """
    aim = np.asarray(scene.target_object.get_center()) * [1.0, 1.0, 0.0]
    towards_base = WORLD_FROM_BASE[:2, 3] - aim[:2]
    base_azimuth = float(np.arctan2(towards_base[1], towards_base[0]))
    for _ in range(_MAX_TRIES):
        d, el = rng.uniform(*distance), rng.uniform(*elevation)
        az = base_azimuth + rng.uniform(-np.deg2rad(40.0), np.deg2rad(40.0))
        eye = aim + d * np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
        pose = look_at(eye, aim)
        q = arm.inverse_kinematics(pose, margin=np.deg2rad(2.0))
        if q is not None:
            return q, arm.camera_pose(q)
    raise RuntimeError("no reachable desired pose; move WORLD_FROM_BASE closer to the table")


@dataclass(frozen=True)
class Start:
    """A start of a servoing run.

    Attributes
    ----------
    q : ndarray, shape (7,)
        Joint positions, radians.
    world_from_camera : ndarray, shape (4, 4)
    translation : float
        Distance between the start and desired optical centres, metres.
    rotation : float
        Angle between the start and desired camera orientations, radians.
    visible_fraction : float
        Share of the object of interest inside the start view's field of view.
    """

    q: NDArray[np.float64]
    world_from_camera: NDArray[np.float64]
    translation: float
    rotation: float
    visible_fraction: float


def sample_start(
    arm: Arm,
    sensor: Sensor,
    scene: Tabletop,
    desired: NDArray,
    rng: np.random.Generator,
    *,
    translation: tuple[float, float] = (0.20, 0.30),
    rotation: tuple[float, float] = (np.deg2rad(30.0), np.deg2rad(40.0)),
    visible: tuple[float, float] = (0.2, 0.9),
    margin: float = np.deg2rad(10.0),
) -> Start:
    """A random reachable start pose far from ``desired``, the object partly out of view.

    The optical centre moves by a random offset of length in ``translation`` (metres, its
    height above the table kept above 0.3 m); the camera aims at a point of the table 10
    to 25 cm from the desired aim, which pushes the object of interest towards the image
    border, and rolls about its optical axis by an angle drawn among those that put the
    angle to the desired orientation in ``rotation`` (radians). Accepted when the share of
    the object of interest inside the image lies in ``visible`` and inverse kinematics
    reaches the pose ``margin`` radians inside every joint limit.

    Returns
    -------
    Start
    """
    eye, forward = desired[:3, 3], desired[:3, 2]
    aim = eye + forward * (-eye[2] / forward[2])  # where the optical axis meets the table
    for _ in range(_MAX_TRIES):
        offset = rng.standard_normal(3)
        offset *= rng.uniform(*translation) / np.linalg.norm(offset)
        start_eye = eye + offset
        if start_eye[2] < 0.3:
            continue
        direction = rng.uniform(0.0, 2.0 * np.pi)
        start_aim = aim + rng.uniform(0.10, 0.25) * np.array([np.cos(direction),
                                                              np.sin(direction), 0.0])
        pose = look_at(start_eye, start_aim)
        angles = [so3.rotation_angle(desired[:3, :3].T @ pose[:3, :3] @ so3.exp([0, 0, r]))
                  for r in _ROLLS]
        rolls = _ROLLS[(rotation[0] <= np.array(angles)) & (np.array(angles) <= rotation[1])]
        if len(rolls) == 0:
            continue
        pose[:3, :3] = pose[:3, :3] @ so3.exp([0.0, 0.0, rng.choice(rolls)])
        angle = so3.rotation_angle(desired[:3, :3].T @ pose[:3, :3])
        fraction = sensor.visible_fraction(scene.target_object, pose)
        if not visible[0] <= fraction <= visible[1]:
            continue
        q = arm.inverse_kinematics(pose, margin=margin)
        if q is None:
            continue
        reached = arm.camera_pose(q)
        return Start(q, reached, float(np.linalg.norm(offset)), float(angle), fraction)
    raise RuntimeError("no start pose met the constraints; widen the ranges")
