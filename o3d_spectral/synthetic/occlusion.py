"""What a camera sees of an object, and an occluder that hides a requested share of it.

Used by :mod:`.scenes` for the ``occluded`` and ``cluttered`` conditions and for every
scan's ``visible_fraction``.
"""

from __future__ import annotations

import numpy as np
import open3d as o3d

from o3d_spectral.synthetic.camera import RenderedView, hit_labels
from o3d_spectral.synthetic.instance import BACKGROUND, MAX_TRIES, SceneOptions
from o3d_spectral.synthetic.models import model_names
from o3d_spectral.synthetic.sampling import (
    model_mesh,
    moved,
    rigid,
    sample_rotation,
    transform_points,
)
from o3d_spectral.synthetic.sensor import CameraIntrinsics

__all__ = ["in_image", "object_pixels", "occlusion_of", "place_occluder", "visible_fraction"]


def visible_fraction(model_points: np.ndarray, view: RenderedView, label: int) -> float:
    """Share of the model's surface (camera-frame samples, (N, 3)) the view sees unhidden."""
    points = model_points
    intr = view.intrinsics
    uv = np.rint(intr.project(points)).astype(np.int64)
    inside = (
        (points[:, 2] > 0)
        & (uv[:, 0] >= 0)
        & (uv[:, 0] < intr.width)
        & (uv[:, 1] >= 0)
        & (uv[:, 1] < intr.height)
    )
    rows, cols = uv[inside, 1], uv[inside, 0]
    seen = (view.ids[rows, cols] == label) & (
        np.abs(view.depth[rows, cols] - points[inside, 2]) < 0.005
    )
    return float(seen.sum() / len(points))


def in_image(
    mesh: o3d.geometry.TriangleMesh, camera_from_world: np.ndarray, intr: CameraIntrinsics
) -> bool:
    """True if all vertices of world-frame ``mesh`` project inside the image, in front."""
    points = transform_points(camera_from_world, np.asarray(mesh.vertices))
    uv = intr.project(points)
    return bool(
        np.all(points[:, 2] > 0) and np.all((uv >= 0) & (uv <= [intr.width - 1, intr.height - 1]))
    )


def object_pixels(
    mesh: o3d.geometry.TriangleMesh, world_from_camera: np.ndarray, intr: CameraIntrinsics
) -> np.ndarray:
    """``(row, column)`` pixels (N, 2) where world-frame ``mesh``, alone, is seen; only the
    mesh's projected bounding box is cast."""
    uv = intr.project(transform_points(np.linalg.inv(world_from_camera), np.asarray(mesh.vertices)))
    lo = np.clip(np.floor(uv.min(axis=0)).astype(int), 0, None)
    hi = np.minimum(np.ceil(uv.max(axis=0)).astype(int), [intr.width - 1, intr.height - 1])
    cols, rows = np.meshgrid(np.arange(lo[0], hi[0] + 1), np.arange(lo[1], hi[1] + 1))
    pixels = np.stack([rows.ravel(), cols.ravel()], axis=1)
    return pixels[hit_labels([mesh], intr, world_from_camera, pixels=pixels) == 0]


def _panel(size: float) -> o3d.geometry.TriangleMesh:
    """A square board ``size`` wide, 1 cm thick, centred at the origin, normal along z."""
    panel = o3d.geometry.TriangleMesh.create_box(size, size, 0.01)
    panel.translate([-size / 2, -size / 2, -0.005])
    panel.compute_triangle_normals()
    return panel


def occlusion_of(
    obj: o3d.geometry.TriangleMesh,
    occluder: o3d.geometry.TriangleMesh,
    pose: np.ndarray,
    pixels: np.ndarray,
    intr: CameraIntrinsics,
) -> float:
    """Share of the object's unoccluded ``pixels`` that the occluder hides."""
    labels = hit_labels([obj, occluder], intr, pose, pixels=pixels, labels=[0, BACKGROUND])
    return float(np.mean(labels != 0))


def place_occluder(
    obj: o3d.geometry.TriangleMesh,
    pose: np.ndarray,
    pixels: np.ndarray,
    requested: float,
    rng: np.random.Generator,
    options: SceneOptions,
    name: str,
) -> tuple[o3d.geometry.TriangleMesh, str, float]:
    """An occluder hiding ``requested`` of the object's pixels (within 1.5 points).

    The occluder (a random other model in a random orientation, or a panel facing the
    camera) sits between camera and object and slides sideways from the line of sight along
    a random image direction; the offset is found by bisection.
    """
    center = np.asarray(obj.get_center())
    eye = pose[:3, 3]
    radius_obj = np.max(np.linalg.norm(np.asarray(obj.vertices) - center, axis=1))
    depth_obj = np.max(np.abs((np.asarray(obj.vertices) - center) @ (center - eye)))
    depth_obj /= np.linalg.norm(center - eye)
    others = [n for n in model_names() if n != name]
    for _ in range(MAX_TRIES):
        if rng.random() < 0.5:
            kind = str(rng.choice(others))
            shape = model_mesh(kind)
            shape = moved(shape, rigid(sample_rotation(rng), -shape.get_center()))
        else:
            kind = "panel"
            shape = moved(_panel(0.6), rigid(pose[:3, :3], np.zeros(3)))
        radius = np.max(np.linalg.norm(np.asarray(shape.vertices), axis=1))
        # Depth: between camera and object, the two depth extents apart (no interpenetration).
        sight = (center - eye) / np.linalg.norm(center - eye)
        extent = np.max(np.abs(np.asarray(shape.vertices) @ sight))
        near, far = 0.15, np.linalg.norm(center - eye) - depth_obj - extent - 0.01
        if far <= near:
            continue
        anchor = eye + rng.uniform(near, far) * sight
        angle = rng.uniform(0, 2 * np.pi)
        slide = pose[:3, :3] @ np.array([np.cos(angle), np.sin(angle), 0.0])

        def occlusion(s: float, shape=shape, anchor=anchor, slide=slide) -> float:
            occluder = moved(shape, rigid(np.eye(3), anchor + s * slide))
            return occlusion_of(obj, occluder, pose, pixels, options.intrinsics)

        lo, hi = 0.0, radius_obj + radius
        if occlusion(lo) < requested or occlusion(hi) > requested:
            continue
        for _ in range(30):
            mid = 0.5 * (lo + hi)
            value = occlusion(mid)
            if abs(value - requested) <= 0.015:
                return moved(shape, rigid(np.eye(3), anchor + mid * slide)), kind, value
            lo, hi = (mid, hi) if value > requested else (lo, mid)
    raise RuntimeError(f"could not occlude {requested:.2f} of {name!r}")
