"""An object's view against a wide tabletop scene: the case of a user who cuts one object
out of a depth image and looks for it in a reconstruction of the whole room or bench.

:func:`wide_scene_instance` lays a table ``width`` metres wide (half as deep, at least
0.5 m) with bundled models resting on it at :data:`OBJECTS_PER_M2` objects per square
metre, the chosen model near its centre and the others spread anywhere (none of them the
chosen model: the object is unique in the scene). The target is the scene as a fused
reconstruction gives it: points sampled on the table top and on every object's surface,
one per :data:`SPACING` squared, with Gaussian noise, in the world frame, without normals.
The source is one depth-camera view of the chosen object, its points cut out by the
object's label (with what its neighbours hide of it), in a random presentation pose.
"""

from __future__ import annotations

import numpy as np
import open3d as o3d

from o3d_spectral.synthetic.camera import look_at, render, scan_from_view
from o3d_spectral.synthetic.constants import MIN_VIEW_POINTS, NOISE, OBJECTS_PER_M2, SPACING
from o3d_spectral.synthetic.instance import BACKGROUND, MAX_TRIES, Instance, SceneOptions
from o3d_spectral.synthetic.models import model_names
from o3d_spectral.synthetic.sampling import rigid, sample_rotation, sample_surface
from o3d_spectral.synthetic.tabletop import table_mesh, tabletop

__all__ = ["wide_scene_instance", "OBJECTS_PER_M2", "SPACING", "NOISE", "MIN_VIEW_POINTS"]


def _sampled(mesh: o3d.geometry.TriangleMesh, rng: np.random.Generator) -> np.ndarray:
    """Points (N, 3) on ``mesh``, one per ``SPACING`` squared of its area, with noise."""
    count = max(1, int(round(mesh.get_surface_area() / SPACING**2)))
    points, _ = sample_surface(mesh, count, rng=rng)
    return points + rng.normal(scale=NOISE, size=points.shape)


def _table_top(size: tuple[float, float], rng: np.random.Generator) -> np.ndarray:
    """Points on the table's top face (z = 0), one per ``SPACING`` squared, with noise."""
    count = int(round(size[0] * size[1] / SPACING**2))
    xy = (rng.random((count, 2)) - 0.5) * np.asarray(size)
    points = np.column_stack([xy, np.zeros(count)])
    return points + rng.normal(scale=NOISE, size=points.shape)


def _view(
    meshes: list[o3d.geometry.TriangleMesh], size: tuple[float, float],
    rng: np.random.Generator, options: SceneOptions,
) -> tuple[np.ndarray, np.ndarray]:
    """A camera pose (world_from_camera) 0.6-1.0 m from the first mesh, 30-70 degrees
    above the table, and the first mesh's points it sees (camera frame, metres)."""
    centre = np.asarray(meshes[0].get_center())
    for _ in range(MAX_TRIES):
        distance = rng.uniform(0.6, 1.0)
        elevation, azimuth = rng.uniform(np.deg2rad(30), np.deg2rad(70)), rng.uniform(0, 2 * np.pi)
        eye = centre + distance * np.array([np.cos(elevation) * np.cos(azimuth),
                                            np.cos(elevation) * np.sin(azimuth),
                                            np.sin(elevation)])
        pose = look_at(eye, centre)
        view = render([table_mesh(size), *meshes], options.intrinsics, pose,
                      labels=[BACKGROUND, *range(len(meshes))])
        scan = scan_from_view(view, noise=options.noise, rng=rng)
        mine = scan.select(scan.object_ids == 0)
        points = np.asarray(mine.to_point_cloud().points)
        if len(points) >= MIN_VIEW_POINTS:
            return pose, points
    raise RuntimeError("no view sees the object with enough points")


def wide_scene_instance(
    name: str, width: float, rng: np.random.Generator, options: SceneOptions | None = None,
) -> Instance:
    """One view of model ``name`` (source) against a reconstructed tabletop ``width``
    metres wide (target).

    Parameters
    ----------
    name : str
        A bundled model (:func:`o3d_spectral.synthetic.models.model_names`).
    width : float
        The table's width (x), metres; it is half as deep (y), and at least 0.5 m.
    rng : numpy.random.Generator
        All the randomness.
    options : SceneOptions, optional
        The camera and its noise.

    Returns
    -------
    Instance
        ``source`` (the view, presented at a random pose), ``target`` (the scene, world
        frame, no normals), ``T_gt`` with ``target ~ T_gt @ source`` on the object, and
        ``metadata`` with ``object``, ``width_m``, ``scene_objects`` and ``scene_points``.
    """
    options = options or SceneOptions()
    size = (float(width), max(0.5, float(width) / 2.0))
    others = [n for n in model_names() if n != name]
    count = max(1, int(round(OBJECTS_PER_M2 * size[0] * size[1])))
    chosen = [name] + [str(n) for n in rng.choice(others, size=count - 1)]
    names, poses, meshes = tabletop(chosen, rng, size, cluster=False)
    world_from_camera, view = _view(meshes, size, rng, options)
    scene = np.concatenate([_table_top(size, rng), *(_sampled(m, rng) for m in meshes)])
    target = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(scene))
    presentation = rigid(sample_rotation(rng), rng.uniform(-0.1, 0.1, size=3))
    source = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(view))
    source.transform(presentation)
    T_gt = world_from_camera @ np.linalg.inv(presentation)
    source_from_model = np.linalg.inv(T_gt) @ poses[0]
    metadata = {"object": name, "condition": "wide", "width_m": size[0], "depth_m": size[1],
                "scene_objects": names, "scene_points": len(scene)}
    labels = np.full(len(scene), BACKGROUND)
    return Instance(source, target, T_gt, labels, source_from_model, metadata)
