"""Two depth views of one object on a turntable: the case of a user who scans an object
from several sides and registers the scans in pairs, with no initial pose.

:func:`turntable_pair` stands a bundled model on a turntable (its mesh frame, the
turntable's axis its +z), puts a depth camera at a random azimuth, ``elevation`` above the
turntable's plane and :data:`DISTANCE` from the model's centre, and scans it; then turns
the table ``angle`` and scans again. Each scan is in its own camera frame, its normals
facing its camera, as a depth sensor's software writes them. The source is the first
scan, the target the second; the truth maps the first camera's frame onto the second's.
"""

from __future__ import annotations

import numpy as np

from o3d_spectral.synthetic.camera import look_at, scan_meshes
from o3d_spectral.synthetic.constants import (
    DISTANCE,
    TURNTABLE_ANGLES,
    TURNTABLE_ELEVATIONS,
    TURNTABLE_MIN_POINTS,
    TURNTABLE_TRIES,
)
from o3d_spectral.synthetic.instance import Instance, SceneOptions
from o3d_spectral.synthetic.sampling import model_mesh

__all__ = ["turntable_pair", "TURNTABLE_ANGLES", "TURNTABLE_ELEVATIONS", "DISTANCE",
           "TURNTABLE_MIN_POINTS"]


def _camera(centre: np.ndarray, azimuth: float, elevation: float) -> np.ndarray:
    """``world_from_camera`` (4, 4) of a camera :data:`DISTANCE` from ``centre`` (3,),
    at ``azimuth`` and ``elevation`` (radians) about the turntable's axis, looking at it."""
    direction = np.array([np.cos(elevation) * np.cos(azimuth),
                          np.cos(elevation) * np.sin(azimuth), np.sin(elevation)])
    return look_at(centre + DISTANCE * direction, centre, up=(0.0, 0.0, 1.0))


def turntable_pair(
    name: str, angle_deg: float, elevation_deg: float, rng: np.random.Generator,
    options: SceneOptions | None = None,
) -> Instance:
    """Two depth views of the model ``name``, the turntable turned ``angle_deg`` between
    them, both at ``elevation_deg`` above its plane (see the module docstring).

    Parameters
    ----------
    name : str
        A bundled model (:func:`o3d_spectral.synthetic.models.model_names`).
    angle_deg, elevation_deg : float
        Degrees.
    rng : numpy.random.Generator
        Draws the first view's azimuth and the sensor noise.
    options : SceneOptions, optional
        Its ``intrinsics`` and ``noise`` are the camera's.

    Returns
    -------
    Instance
        ``source``: the first view in its camera's frame; ``target``: the second in its
        own; ``T_gt``: the first camera's frame onto the second's; the model's symmetry
        through ``source_from_model``; ``metadata``: the model, angle, elevation, azimuth
        and both cameras' poses in the model's frame.

    Raises
    ------
    RuntimeError
        If no azimuth of :data:`TURNTABLE_TRIES` gives both views :data:`TURNTABLE_MIN_POINTS`.
    """
    options = options or SceneOptions()
    mesh = model_mesh(name)
    centre = np.asarray(mesh.get_center())
    for _ in range(TURNTABLE_TRIES):
        azimuth = rng.uniform(0.0, 2.0 * np.pi)
        poses = [_camera(centre, azimuth + np.deg2rad(turn), np.deg2rad(elevation_deg))
                 for turn in (0.0, angle_deg)]
        scans = [scan_meshes([mesh], options.intrinsics, pose, noise=options.noise, rng=rng)
                 for pose in poses]
        if min(len(scan.points) for scan in scans) >= TURNTABLE_MIN_POINTS:
            break
    else:
        raise RuntimeError(f"no turntable view of {name} shows {TURNTABLE_MIN_POINTS} points")
    source_pose, target_pose = poses
    metadata = {
        "object": name, "scene_objects": [name], "angle_deg": float(angle_deg),
        "elevation_deg": float(elevation_deg), "azimuth_deg": float(np.rad2deg(azimuth)),
        "world_from_cameras": [source_pose.tolist(), target_pose.tolist()],
    }
    return Instance(
        scans[0].to_point_cloud(), scans[1].to_point_cloud(),
        np.linalg.inv(target_pose) @ source_pose, np.zeros(len(scans[1].points), np.int64),
        np.linalg.inv(source_pose), metadata,
    )
