"""Registration instances built from the bundled object models, one per condition.

Every instance is a source cloud (the object model sampled on its mesh, in a random
presentation pose), a target cloud and the ground truth ``T_gt`` (4x4) with
``target ~ T_gt @ source`` on the object's points. The conditions:

``full`` (C-1)
    The target is an independently sampled copy of the model with Gaussian noise.
``partial`` (C-2)
    The target is one depth-camera view of the object alone (camera frame).
``occluded``
    A view in which an occluder (another object or a panel) between camera and object hides
    a requested fraction of the object's pixels; only the object's points are kept (as after
    a perfect segmentation), so occlusion is separated from clutter.
``cluttered`` (C-3)
    A tabletop with 3-8 objects viewed from above; the target is the whole scene cloud,
    table included, and the source is one of the objects.

The presentation pose: the initial rotation (``R`` of ``T_gt``) is drawn uniformly over
SO(3), or with a uniform axis and an angle uniform in ``angle_range``; the source's object
centroid sits at the target's object centroid minus an offset of uniform direction and a
length uniform in ``[0, max_offset]``. See ``docs/suites.md`` for the full description.
"""

from __future__ import annotations

import numpy as np
import open3d as o3d
from scipy.spatial.transform import Rotation

from o3d_spectral.synthetic.camera import hit_labels, look_at, render, scan_from_view
from o3d_spectral.synthetic.instance import (
    BACKGROUND,
    CONDITIONS,
    MAX_TRIES,
    Instance,
    SceneOptions,
)
from o3d_spectral.synthetic.models import model_names
from o3d_spectral.synthetic.occlusion import (
    in_image,
    object_pixels,
    place_occluder,
    visible_fraction,
)
from o3d_spectral.synthetic.sampling import (
    model_cloud,
    model_mesh,
    point_cloud,
    random_direction,
    rigid,
    sample_rotation,
    sample_surface,
    transform_points,
)
from o3d_spectral.synthetic.tabletop import table_mesh, tabletop

__all__ = ["make_instance"]


def _present_source(
    name: str, target_from_model: np.ndarray, *, rng: np.random.Generator, options: SceneOptions
) -> tuple[o3d.geometry.PointCloud, np.ndarray, np.ndarray, dict]:
    """Source cloud in a random presentation pose and the ground truth that undoes it.

    ``T_gt`` has rotation ``R`` from the rotation law and moves the source's object centroid
    onto the target's, which sits ``offset`` away (``|offset| <= max_offset``).
    """
    points, normals = model_cloud(name, options.source_points)
    rotation = sample_rotation(rng, angle_range=options.angle_range)
    offset = random_direction(rng) * rng.uniform(0.0, options.max_offset)
    center_target = transform_points(target_from_model, points.mean(axis=0, keepdims=True))[0]
    center_source = center_target - offset
    t_gt = rigid(rotation, center_target - rotation @ center_source)
    source_from_model = np.linalg.inv(t_gt) @ target_from_model
    source = point_cloud(
        transform_points(source_from_model, points), normals @ source_from_model[:3, :3].T
    )
    info = {
        "init_angle_deg": float(np.rad2deg(Rotation.from_matrix(rotation).magnitude())),
        "init_offset_m": float(np.linalg.norm(offset)),
    }
    return source, t_gt, source_from_model, info


def _scan_metadata(view_pose: np.ndarray, distance: float) -> dict:
    return {"world_from_camera": view_pose.tolist(), "camera_distance_m": float(distance)}


def _full(name: str, rng: np.random.Generator, options: SceneOptions) -> Instance:
    mesh = model_mesh(name)
    points, normals = sample_surface(mesh, options.source_points, rng=rng)
    points = points + rng.normal(scale=options.full_noise_sigma, size=points.shape)
    source, t_gt, source_from_model, info = _present_source(
        name, np.eye(4), rng=rng, options=options
    )
    meta = {
        "scene_objects": [name],
        "object_poses": [np.eye(4).tolist()],
        "visible_fraction": 1.0,
        "occlusion": 0.0,
        "view": None,
    }
    meta.update(info)
    return Instance(
        source,
        point_cloud(points, normals),
        t_gt,
        np.zeros(len(points), np.int64),
        source_from_model,
        meta,
    )


def _object_view(
    mesh: o3d.geometry.TriangleMesh, rng: np.random.Generator, options: SceneOptions
) -> tuple[np.ndarray, float]:
    """A camera pose (world_from_camera) seeing the whole world-frame ``mesh`` at a working
    distance from a uniformly random direction, with random roll; and that distance."""
    center = np.asarray(mesh.get_center())
    for _ in range(MAX_TRIES):
        distance = rng.uniform(*options.distance_range)
        eye = center + distance * random_direction(rng)
        aim = center + rng.uniform(-0.03, 0.03, size=3)
        try:
            pose = look_at(eye, aim, up=random_direction(rng))
        except ValueError:
            continue
        if in_image(mesh, np.linalg.inv(pose), options.intrinsics):
            return pose, float(distance)
    raise RuntimeError("could not place the camera to see the whole object; widen distance_range")


def _scan_instance(
    name: str,
    meshes: list[o3d.geometry.TriangleMesh],
    labels: list[int],
    pose: np.ndarray,
    *,
    keep: str,
    rng: np.random.Generator,
    options: SceneOptions,
    meta: dict,
) -> Instance:
    """Render world-frame ``meshes`` (the object is label 0) from ``pose``, scan with noise,
    keep ``"object"`` or ``"all"`` points; ``meta["world_from_objects"]`` (object first)
    becomes the target-frame ``meta["object_poses"]``."""
    view = render(meshes, options.intrinsics, pose, labels=labels)
    scan = scan_from_view(view, noise=options.noise, rng=rng)
    if keep == "object":
        scan = scan.select(scan.object_ids == 0)
    camera_from_world = np.linalg.inv(pose)
    object_poses = [camera_from_world @ w for w in meta.pop("world_from_objects")]
    meta["object_poses"] = [p.tolist() for p in object_poses]
    target_from_model = object_poses[0]
    source, t_gt, source_from_model, info = _present_source(
        name, target_from_model, rng=rng, options=options
    )
    meta.update(info)
    model_points = model_cloud(name, options.source_points)[0]
    meta["visible_fraction"] = visible_fraction(
        transform_points(target_from_model, model_points), view, 0
    )
    return Instance(
        source, scan.to_point_cloud(), t_gt, scan.object_ids.copy(), source_from_model, meta
    )


def _partial(name: str, rng: np.random.Generator, options: SceneOptions) -> Instance:
    mesh = model_mesh(name)
    pose, distance = _object_view(mesh, rng, options)
    meta = {
        "scene_objects": [name],
        "occlusion": 0.0,
        "view": _scan_metadata(pose, distance),
        "world_from_objects": [np.eye(4)],
    }
    return _scan_instance(
        name, [mesh], [0], pose, keep="object", rng=rng, options=options, meta=meta
    )


def _occluded(
    name: str, rng: np.random.Generator, options: SceneOptions, occlusion: float | None
) -> Instance:
    mesh = model_mesh(name)
    pose, distance = _object_view(mesh, rng, options)
    requested = rng.uniform(*options.occlusion_range) if occlusion is None else occlusion
    pixels = object_pixels(mesh, pose, options.intrinsics)
    occluder, kind, measured = place_occluder(mesh, pose, pixels, requested, rng, options, name)
    meta = {
        "scene_objects": [name],
        "occlusion": measured,
        "occlusion_requested": float(requested),
        "occluder": kind,
        "view": _scan_metadata(pose, distance),
        "world_from_objects": [np.eye(4)],
    }
    return _scan_instance(
        name,
        [mesh, occluder],
        [0, BACKGROUND],
        pose,
        keep="object",
        rng=rng,
        options=options,
        meta=meta,
    )


def _clutter_view(
    name: str,
    meshes: list[o3d.geometry.TriangleMesh],
    rng: np.random.Generator,
    options: SceneOptions,
) -> tuple[np.ndarray, np.ndarray, float]:
    """A camera pose (world_from_camera) above the table that sees the chosen object
    (``meshes[0]``) whole in the image and at least ``min_visible`` of it unhidden; the
    camera's eye and the object's measured occlusion."""
    obj = meshes[0]
    center = np.asarray(obj.get_center())
    # Look across the other objects at the chosen one half of the time, so that it is
    # partly hidden as often as in real clutter; from anywhere the other half.
    across = 0.0
    if len(meshes) > 1:
        toward = np.mean([m.get_center() for m in meshes[1:]], axis=0) - center
        across = float(np.arctan2(toward[1], toward[0]))
    for _ in range(MAX_TRIES):
        distance = rng.uniform(0.6, 1.2)
        elevation = rng.uniform(np.deg2rad(25), np.deg2rad(75))
        if rng.random() < 0.5:
            azimuth = across + rng.uniform(-np.pi / 3, np.pi / 3)
        else:
            azimuth = rng.uniform(0, 2 * np.pi)
        aim = 0.5 * center + rng.uniform(-0.05, 0.05, size=3) * [1, 1, 0]
        eye = aim + distance * np.array(
            [
                np.cos(elevation) * np.cos(azimuth),
                np.cos(elevation) * np.sin(azimuth),
                np.sin(elevation),
            ]
        )
        pose = look_at(eye, aim)
        if not in_image(obj, np.linalg.inv(pose), options.intrinsics):
            continue
        alone = object_pixels(obj, pose, options.intrinsics)
        if len(alone) == 0:
            continue
        labels = hit_labels(
            [table_mesh(), *meshes],
            options.intrinsics,
            pose,
            pixels=alone,
            labels=[BACKGROUND, *range(len(meshes))],
        )
        occlusion = float(np.mean(labels != 0))
        if 1 - occlusion >= options.min_visible:
            return pose, eye, occlusion
    raise RuntimeError(f"no view sees {name!r} enough; lower min_visible")


def _cluttered(name: str, rng: np.random.Generator, options: SceneOptions) -> Instance:
    others = [n for n in model_names() if n != name]
    count = int(rng.integers(options.clutter_objects[0], options.clutter_objects[1] + 1))
    chosen = [name] + [str(n) for n in rng.choice(others, size=count - 1, replace=False)]
    names, poses, meshes = tabletop(chosen, rng)
    pose, eye, occlusion = _clutter_view(name, meshes, rng, options)
    center = np.asarray(meshes[0].get_center())
    meta = {
        "occlusion": occlusion,
        "scene_objects": names,
        "view": _scan_metadata(pose, float(np.linalg.norm(eye - center))),
        "world_from_objects": poses,
    }
    return _scan_instance(
        name,
        [table_mesh(), *meshes],
        [BACKGROUND, *range(len(meshes))],
        pose,
        keep="all",
        rng=rng,
        options=options,
        meta=meta,
    )


def make_instance(
    condition: str,
    name: str,
    *,
    rng: np.random.Generator,
    options: SceneOptions | None = None,
    occlusion: float | None = None,
) -> Instance:
    """Build one registration instance.

    Parameters
    ----------
    condition : {"full", "partial", "occluded", "cluttered"}
        See the module docstring.
    name : str
        Bundled model name (see :func:`o3d_spectral.synthetic.models.model_names`).
    rng : numpy.random.Generator
        Every random choice is drawn from it, so a seeded generator gives the same instance.
    options : SceneOptions, optional
        Generator settings (defaults: ``SceneOptions()``).
    occlusion : float, optional
        ``occluded`` only: the fraction of the object's pixels to hide (default: uniform
        in ``options.occlusion_range``).

    Returns
    -------
    Instance
        Source, target, ground truth and metadata.
    """
    options = SceneOptions() if options is None else options
    if condition not in CONDITIONS:
        raise ValueError(f"condition must be one of {', '.join(CONDITIONS)}; got {condition!r}")
    if name not in model_names():
        raise ValueError(f"unknown model {name!r}; available: {', '.join(model_names())}")
    if occlusion is not None and (condition != "occluded" or not 0 <= occlusion < 1):
        raise ValueError(f"occlusion must be in [0, 1) and only for 'occluded', got {occlusion}")
    if condition == "full":
        instance = _full(name, rng, options)
    elif condition == "partial":
        instance = _partial(name, rng, options)
    elif condition == "occluded":
        instance = _occluded(name, rng, options, occlusion)
    else:
        instance = _cluttered(name, rng, options)
    instance.metadata = {
        "condition": condition,
        "object": name,
        "n_source": len(instance.source.points),
        "n_target": len(instance.target.points),
        **instance.metadata,
    }
    return instance
