"""Virtual depth camera: pinhole rays cast into Open3D meshes, with a sensor noise model
(:mod:`.sensor`).

Frames follow the OpenCV convention: the camera looks along its +z axis, x points right
and y down in the image. Poses are 4x4 float64 matrices; ``world_from_camera`` maps camera
coordinates to world coordinates. Depth ``z`` is the distance along the optical axis
(not along the ray), in metres.

Typical use::

    intrinsics = CameraIntrinsics()                      # 640x480, 60 degrees wide
    pose = look_at(eye=[0.0, -0.5, 0.5], target=[0.0, 0.0, 0.0])
    scan = scan_meshes([mesh], intrinsics, pose, rng=np.random.default_rng(0))
    cloud = scan.to_point_cloud()                        # camera frame, normals to camera
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import open3d as o3d

from o3d_spectral.synthetic.sensor import CameraIntrinsics, DepthNoise

__all__ = [
    "RenderedView",
    "Scan",
    "hit_labels",
    "look_at",
    "render",
    "scan_from_view",
    "scan_meshes",
]

_EPS = 1e-12


@dataclass(frozen=True)
class RenderedView:
    """Noise-free per-pixel raycast result (images indexed ``[row, column]``).

    Attributes
    ----------
    depth : ndarray, shape (H, W), float64
        Depth along the optical axis (m); ``inf`` where no surface is hit.
    normals : ndarray, shape (H, W, 3), float64
        Unit normals of the triangles hit, camera frame, oriented towards the camera.
    ids : ndarray, shape (H, W), int64
        Label of the mesh hit (the ``labels`` passed to :func:`render`); -2 for no hit.
    cos_incidence : ndarray, shape (H, W), float64
        Cosine of the angle between the viewing ray and the surface normal.
    intrinsics : CameraIntrinsics
        The camera that produced the view.
    """

    depth: np.ndarray
    normals: np.ndarray
    ids: np.ndarray
    cos_incidence: np.ndarray
    intrinsics: CameraIntrinsics


@dataclass(frozen=True)
class Scan:
    """Points a depth sensor returns, in the camera frame.

    Attributes
    ----------
    points : ndarray, shape (N, 3), float64
        Camera-frame points (m), ``z > 0``.
    normals : ndarray, shape (N, 3), float64
        Unit normals of the surfaces hit, flipped to face the camera.
    object_ids : ndarray, shape (N,), int64
        Label of the mesh each point comes from.
    pixels : ndarray, shape (N, 2), int64
        ``(row, column)`` of each point in the image.
    """

    points: np.ndarray
    normals: np.ndarray
    object_ids: np.ndarray
    pixels: np.ndarray

    def to_point_cloud(self) -> o3d.geometry.PointCloud:
        """Open3D point cloud with points and normals (object ids are not kept)."""
        cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(self.points))
        cloud.normals = o3d.utility.Vector3dVector(self.normals)
        return cloud

    def select(self, mask: np.ndarray) -> Scan:
        """The points where boolean ``mask`` (N,) is true."""
        return Scan(self.points[mask], self.normals[mask], self.object_ids[mask], self.pixels[mask])


def look_at(
    eye: Sequence[float] | np.ndarray,
    target: Sequence[float] | np.ndarray,
    *,
    up: Sequence[float] | np.ndarray = (0.0, 0.0, 1.0),
) -> np.ndarray:
    """``world_from_camera`` pose (4x4 float64) of a camera at ``eye`` looking at ``target``.

    The image's "up" (-y) is as close as possible to the world direction ``up``. All
    arguments are world-frame 3-vectors (m).
    """
    eye = np.asarray(eye, dtype=float)
    forward = np.asarray(target, dtype=float) - eye
    norm = np.linalg.norm(forward)
    if norm < 1e-9:
        raise ValueError("eye and target must differ")
    z = forward / norm
    x = np.cross(z, np.asarray(up, dtype=float))
    if np.linalg.norm(x) < 1e-6:
        raise ValueError(f"up={tuple(up)} is parallel to the viewing direction; pass another up")
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    pose = np.eye(4)
    pose[:3, :3] = np.stack([x, y, z], axis=1)
    pose[:3, 3] = eye
    return pose


def _camera_rays(intrinsics: CameraIntrinsics) -> np.ndarray:
    """Camera-frame ray directions with unit z, shape (H, W, 3): ``t_hit`` is then depth."""
    u = np.arange(intrinsics.width, dtype=float)
    v = np.arange(intrinsics.height, dtype=float)
    uu, vv = np.meshgrid(u, v)
    return np.stack(
        [
            (uu - intrinsics.cx) / intrinsics.fx,
            (vv - intrinsics.cy) / intrinsics.fy,
            np.ones_like(uu),
        ],
        axis=-1,
    )


def _check_scene(
    meshes: Sequence[o3d.geometry.TriangleMesh],
    labels: Sequence[int] | None,
    world_from_camera: np.ndarray,
) -> tuple[list[int], np.ndarray]:
    labels = list(range(len(meshes))) if labels is None else [int(x) for x in labels]
    if len(labels) != len(meshes):
        raise ValueError(f"labels has {len(labels)} entries for {len(meshes)} meshes")
    if min(labels, default=0) < -1:
        raise ValueError(f"labels must be >= -1, got {min(labels)}")
    world_from_camera = np.asarray(world_from_camera, dtype=float)
    if world_from_camera.shape != (4, 4):
        raise ValueError(f"world_from_camera must be 4x4, got shape {world_from_camera.shape}")
    return labels, world_from_camera


def _cast(
    meshes: Sequence[o3d.geometry.TriangleMesh],
    labels: list[int],
    world_from_camera: np.ndarray,
    directions: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cast camera-frame ``directions`` (..., 3), unit z, from the camera centre.

    Returns depth (...) with ``inf`` for misses, labels (...) with -2 for misses, and
    world-frame triangle normals (..., 3) as Open3D reports them.
    """
    scene = o3d.t.geometry.RaycastingScene()
    gids = [scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(m)) for m in meshes]
    label_of_gid = np.full(max(gids, default=0) + 1, -2, dtype=np.int64)
    label_of_gid[gids] = labels
    rotation, origin = world_from_camera[:3, :3], world_from_camera[:3, 3]
    directions_world = directions @ rotation.T
    rays = np.concatenate(
        [np.broadcast_to(origin, directions_world.shape), directions_world], axis=-1
    ).astype(np.float32)
    hit = scene.cast_rays(o3d.core.Tensor(rays))
    depth = hit["t_hit"].numpy().astype(float)
    valid = np.isfinite(depth)
    ids = np.full(depth.shape, -2, dtype=np.int64)
    ids[valid] = label_of_gid[hit["geometry_ids"].numpy()[valid].astype(np.int64)]
    return depth, ids, hit["primitive_normals"].numpy().astype(float)


def render(
    meshes: Sequence[o3d.geometry.TriangleMesh],
    intrinsics: CameraIntrinsics,
    world_from_camera: np.ndarray,
    *,
    labels: Sequence[int] | None = None,
) -> RenderedView:
    """Cast one ray per pixel into world-frame ``meshes`` with Open3D's ``RaycastingScene``.

    Parameters
    ----------
    meshes : sequence of open3d.geometry.TriangleMesh
        Scene geometry in world coordinates (m).
    intrinsics : CameraIntrinsics
        Pinhole camera.
    world_from_camera : ndarray, shape (4, 4)
        Camera pose, e.g. from :func:`look_at`.
    labels : sequence of int, optional
        Label per mesh written into ``RenderedView.ids`` (default ``0..len(meshes)-1``).
        Must be >= -1; -2 marks pixels with no hit.

    Returns
    -------
    RenderedView
        Exact (noise-free) depth, normals and labels per pixel.
    """
    labels, world_from_camera = _check_scene(meshes, labels, world_from_camera)
    directions = _camera_rays(intrinsics)
    depth, ids, normals = _cast(meshes, labels, world_from_camera, directions)
    valid = np.isfinite(depth)
    # Triangle normals into the camera frame, flipped to face the camera.
    normals = normals @ world_from_camera[:3, :3]
    normals /= np.maximum(np.linalg.norm(normals, axis=-1, keepdims=True), _EPS)
    ray_unit = directions / np.linalg.norm(directions, axis=-1, keepdims=True)
    cos = np.einsum("hwk,hwk->hw", normals, ray_unit)
    normals = np.where((cos > 0)[..., None], -normals, normals)
    normals[~valid] = 0.0
    return RenderedView(
        depth=depth,
        normals=normals,
        ids=ids,
        cos_incidence=np.where(valid, np.abs(cos), 0.0),
        intrinsics=intrinsics,
    )


def hit_labels(
    meshes: Sequence[o3d.geometry.TriangleMesh],
    intrinsics: CameraIntrinsics,
    world_from_camera: np.ndarray,
    *,
    pixels: np.ndarray,
    labels: Sequence[int] | None = None,
) -> np.ndarray:
    """Label of the first surface hit at selected pixels only (cheaper than :func:`render`).

    Parameters
    ----------
    meshes, intrinsics, world_from_camera, labels
        As for :func:`render`.
    pixels : ndarray, shape (N, 2), int
        ``(row, column)`` of the pixels to cast.

    Returns
    -------
    ndarray, shape (N,), int64
        Mesh label per pixel, -2 where nothing is hit.
    """
    labels, world_from_camera = _check_scene(meshes, labels, world_from_camera)
    pixels = np.asarray(pixels)
    if pixels.ndim != 2 or pixels.shape[1] != 2:
        raise ValueError(f"pixels must have shape (N, 2), got {pixels.shape}")
    directions = np.stack(
        [
            (pixels[:, 1] - intrinsics.cx) / intrinsics.fx,
            (pixels[:, 0] - intrinsics.cy) / intrinsics.fy,
            np.ones(len(pixels)),
        ],
        axis=1,
    )
    return _cast(meshes, labels, world_from_camera, directions)[1]


def scan_from_view(
    view: RenderedView, *, noise: DepthNoise | None = None, rng: np.random.Generator
) -> Scan:
    """Turn a rendered view into sensor points: noise, quantisation, range and dropout.

    Parameters
    ----------
    view : RenderedView
        Output of :func:`render`.
    noise : DepthNoise, optional
        Sensor model (default ``DepthNoise()``); ``DepthNoise.noiseless()`` keeps exact
        depths (still limited to the working range).
    rng : numpy.random.Generator
        Source of the noise.

    Returns
    -------
    Scan
        Valid points in row-major pixel order, camera frame (m).
    """
    noise = DepthNoise() if noise is None else noise
    intr = view.intrinsics
    hit = np.isfinite(view.depth) & (view.cos_incidence >= np.cos(noise.max_incidence) - 1e-12)
    rows, cols = np.nonzero(hit)
    depth = noise.apply(view.depth[rows, cols], fx=intr.fx, rng=rng)
    keep = np.isfinite(depth)
    rows, cols, depth = rows[keep], cols[keep], depth[keep]
    points = np.stack(
        [(cols - intr.cx) / intr.fx * depth, (rows - intr.cy) / intr.fy * depth, depth], axis=1
    )
    return Scan(
        points=points,
        normals=view.normals[rows, cols],
        object_ids=view.ids[rows, cols],
        pixels=np.stack([rows, cols], axis=1).astype(np.int64),
    )


def scan_meshes(
    meshes: Sequence[o3d.geometry.TriangleMesh],
    intrinsics: CameraIntrinsics,
    world_from_camera: np.ndarray,
    *,
    labels: Sequence[int] | None = None,
    noise: DepthNoise | None = None,
    rng: np.random.Generator,
) -> Scan:
    """Depth scan of world-frame ``meshes``: :func:`render` followed by :func:`scan_from_view`.

    See those functions for the parameters. Points are in the camera frame (m), normals face
    the camera, ``object_ids`` hold the mesh ``labels``.
    """
    view = render(meshes, intrinsics, world_from_camera, labels=labels)
    return scan_from_view(view, noise=noise, rng=rng)
