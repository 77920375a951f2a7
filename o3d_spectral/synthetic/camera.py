"""Virtual depth camera: pinhole rays cast into Open3D meshes, with a sensor noise model.

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

__all__ = [
    "CameraIntrinsics",
    "DepthNoise",
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
class CameraIntrinsics:
    """Pinhole intrinsics (pixels).

    The defaults are a 640x480 sensor with a 60 degree horizontal field of view
    (``fx = fy = 320 / tan(30 deg)``) and the principal point at the image centre.
    Pixel ``(u, v)`` has its centre at column ``u``, row ``v``.
    """

    width: int = 640
    height: int = 480
    fx: float = 554.2562584220407
    fy: float = 554.2562584220407
    cx: float = 319.5
    cy: float = 239.5

    def __post_init__(self) -> None:
        if self.width < 1 or self.height < 1:
            raise ValueError(f"width and height must be >= 1, got {self.width}x{self.height}")
        if self.fx <= 0 or self.fy <= 0:
            raise ValueError(f"fx and fy must be > 0, got fx={self.fx}, fy={self.fy}")

    @classmethod
    def from_fov(cls, *, width: int = 640, height: int = 480, fov: float) -> CameraIntrinsics:
        """Square-pixel intrinsics from a horizontal field of view ``fov`` (radians)."""
        if not 0 < fov < np.pi:
            raise ValueError(f"fov must be in (0, pi) radians, got {fov}")
        f = 0.5 * width / np.tan(0.5 * fov)
        return cls(width=width, height=height, fx=f, fy=f, cx=(width - 1) / 2, cy=(height - 1) / 2)

    @property
    def matrix(self) -> np.ndarray:
        """The 3x3 calibration matrix ``K`` (float64)."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def project(self, points: np.ndarray) -> np.ndarray:
        """Pixel coordinates ``(u, v)``, shape (N, 2), of camera-frame ``points`` (N, 3)."""
        z = np.maximum(points[:, 2], _EPS)
        return np.stack(
            [self.fx * points[:, 0] / z + self.cx, self.fy * points[:, 1] / z + self.cy], axis=1
        )


@dataclass(frozen=True)
class DepthNoise:
    """Depth-sensor model: axial Gaussian noise, disparity quantisation, range and dropout.

    Parameters
    ----------
    sigma_0, sigma_quadratic, sigma_offset : float
        Axial standard deviation ``sigma(z) = sigma_0 + sigma_quadratic * (z - sigma_offset)**2``
        in metres; the defaults are the structured-light (Kinect) fit of Nguyen et al.
        (2012): 1.2 mm at 0.4 m, 1.9 mm at 1 m, 5.8 mm at 2 m.
    baseline : float
        Projector-camera baseline (m) of the triangulation used for quantisation.
    disparity_step : float
        Disparity resolution (pixels). Depth is quantised as ``z = fx * baseline / d``
        with ``d`` rounded to this step, so the depth step grows as ``z**2``
        (about 3 mm at 1 m with the defaults). Zero disables quantisation.
    min_depth, max_depth : float
        Working range (m); pixels outside it are invalid (missing).
    max_incidence : float
        Surfaces seen at a larger angle (radians) between ray and normal return nothing,
        as on a real sensor at grazing incidence.

    References
    ----------
    C. V. Nguyen, S. Izadi, D. Lovell, "Modeling Kinect sensor noise for improved 3D
    reconstruction and tracking", 3DIMPVT 2012, doi:10.1109/3DIMPVT.2012.84.
    """

    sigma_0: float = 0.0012
    sigma_quadratic: float = 0.0019
    sigma_offset: float = 0.4
    baseline: float = 0.075
    disparity_step: float = 0.125
    min_depth: float = 0.2
    max_depth: float = 3.0
    max_incidence: float = np.deg2rad(80.0)

    def __post_init__(self) -> None:
        if self.sigma_0 < 0 or self.sigma_quadratic < 0:
            raise ValueError(
                f"sigma_0 and sigma_quadratic must be >= 0, got {self.sigma_0}, "
                f"{self.sigma_quadratic}"
            )
        if self.baseline <= 0 or self.disparity_step < 0:
            raise ValueError(
                f"baseline must be > 0 and disparity_step >= 0, got {self.baseline}, "
                f"{self.disparity_step}"
            )
        if not 0 <= self.min_depth < self.max_depth:
            raise ValueError(
                f"need 0 <= min_depth < max_depth, got {self.min_depth}, {self.max_depth}"
            )

    @classmethod
    def noiseless(cls) -> DepthNoise:
        """Exact depths: no noise, no quantisation, no grazing dropout (same range)."""
        return cls(sigma_0=0.0, sigma_quadratic=0.0, disparity_step=0.0, max_incidence=np.pi / 2)

    def sigma(self, depth: np.ndarray) -> np.ndarray:
        """Axial standard deviation (m) at ``depth`` (m), any shape."""
        return self.sigma_0 + self.sigma_quadratic * (depth - self.sigma_offset) ** 2

    def apply(self, depth: np.ndarray, *, fx: float, rng: np.random.Generator) -> np.ndarray:
        """Noisy, quantised copy of ``depth`` (m), shape (N,). Invalid results are NaN."""
        noisy = depth + rng.standard_normal(depth.shape) * self.sigma(depth)
        if self.disparity_step > 0:
            # Triangulation: depth comes from a disparity measured in steps of disparity_step.
            fb = fx * self.baseline
            disparity = np.round(fb / np.maximum(noisy, _EPS) / self.disparity_step)
            noisy = fb / np.maximum(disparity * self.disparity_step, _EPS)
        return np.where((noisy >= self.min_depth) & (noisy <= self.max_depth), noisy, np.nan)


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
