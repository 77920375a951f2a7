"""The BOP benchmark's pose-error metrics: VSD, MSSD, MSPD and their average recall.

As defined for the BOP Challenge 2019 and later (Hodan et al., ECCV Workshops 2020), in
metres rather than BOP's millimetres:

* **VSD**, visible surface discrepancy: the model is rendered at the estimated and the
  true pose; over the pixels where either rendering is visible in the test depth image
  (within ``delta``), the share whose distances differ by ``tau`` or more, counting a
  pixel visible in only one of them as differing. It sees only what the view shows, so
  a pose that differs where the camera cannot see is not penalised. ``delta`` is 15 mm,
  ``tau`` runs over 0.05, 0.10, ..., 0.50 of the object's diameter, and an estimate is
  correct for a ``tau`` when the error is below a threshold in 0.05, 0.10, ..., 0.5.
* **MSSD**, maximum symmetry-aware surface distance (m): the largest distance between a
  model point at the estimated pose and at the true pose, minimised over the object's
  symmetries; correct below 0.05, 0.10, ..., 0.50 of the diameter.
* **MSPD**, maximum symmetry-aware projection distance (pixels): the same on the
  points' images; correct below 5, 10, ..., 50 pixels times ``width / 640``.
* **AR**: the mean of the three recalls, each the share of correct estimates averaged
  over its thresholds (and over ``tau`` for VSD). An estimate that is missing counts
  as wrong at every threshold.

Depth images are rendered with Open3D's ray casting (``open3d.t.geometry.RaycastingScene``)
through the pixels' integer coordinates (pixel ``(u, v)`` looks along
``K^-1 (u, v, 1)``), the convention of BOP's depth back-projection; VSD compares
distances from the camera centre, as BOP does since 2019 (depth along each pixel's ray).

Transforms are 4x4 float64 arrays mapping model points into the camera frame
(``p_cam = T @ p_model``); intrinsics ``K`` are 3x3 (pixels).

References
----------
T. Hodan, M. Sundermeyer, B. Drost et al., "BOP Challenge 2020 on 6D Object Localization",
ECCV Workshops 2020, doi:10.1007/978-3-030-66096-3_39.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import open3d as o3d

from o3d_spectral.harness.constants import (
    CONTINUOUS_STEPS,
    MSPD_THRESHOLDS_PX,
    MSSD_THRESHOLDS,
    VSD_DELTA_M,
    VSD_TAUS,
    VSD_THRESHOLDS,
)
from o3d_spectral.harness.errors import mssd as _mssd
from o3d_spectral.synthetic.symmetry import Symmetry

__all__ = [
    "CONTINUOUS_STEPS",
    "MSPD_THRESHOLDS_PX",
    "MSSD_THRESHOLDS",
    "VSD_DELTA_M",
    "VSD_TAUS",
    "VSD_THRESHOLDS",
    "average_recall",
    "mspd",
    "mspd_recall",
    "mssd",
    "mssd_recall",
    "render_depth",
    "symmetry_elements",
    "vsd",
    "vsd_recall",
]


def symmetry_elements(symmetry: Symmetry | None) -> np.ndarray:
    """The symmetry group as BOP samples it: its discrete elements, each composed with
    :data:`CONTINUOUS_STEPS` rotations about the continuous axis when it has one.

    Returns
    -------
    ndarray, shape (M, 4, 4), float64
        The identity first.
    """
    if symmetry is None:
        return np.eye(4)[None]
    return symmetry.elements(step=2.0 * np.pi / CONTINUOUS_STEPS)


def mssd(
    T_est: np.ndarray, T_gt: np.ndarray, points: np.ndarray, symmetry: Symmetry | None = None
) -> float:
    """Maximum symmetry-aware surface distance (m):
    ``min_S max_x ||T_est x - T_gt S x||`` over model ``points`` (N, 3) in metres, ``S``
    over :func:`symmetry_elements`."""
    return _mssd(T_est, T_gt, points, symmetry, step=2.0 * np.pi / CONTINUOUS_STEPS)


def _project(K: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Pixel coordinates (N, 2) of camera-frame ``points`` (N, 3)."""
    image = points @ np.asarray(K, dtype=np.float64).T
    return image[:, :2] / image[:, 2:3]


def mspd(
    T_est: np.ndarray,
    T_gt: np.ndarray,
    points: np.ndarray,
    K: np.ndarray,
    symmetry: Symmetry | None = None,
) -> float:
    """Maximum symmetry-aware projection distance (pixels):
    ``min_S max_x ||proj(K T_est x) - proj(K T_gt S x)||``.

    Parameters
    ----------
    T_est, T_gt : ndarray, shape (4, 4)
        Model-to-camera poses.
    points : ndarray, shape (N, 3)
        Model points (m), in front of the camera at both poses.
    K : ndarray, shape (3, 3)
        Camera intrinsics (pixels).
    symmetry : Symmetry, optional
        The model's symmetry group in its own frame.

    Returns
    -------
    float
        Pixels; infinite when the estimate puts a point at or behind the camera's plane.
    """
    points = np.asarray(points, dtype=np.float64)
    t_est = np.asarray(T_est, dtype=np.float64)
    posed = points @ t_est[:3, :3].T + t_est[:3, 3]
    if np.any(posed[:, 2] <= 0.0):  # not all in front of the camera: no image to compare
        return float("inf")
    seen = _project(K, posed)
    best = np.inf
    for pose in np.asarray(T_gt, dtype=np.float64) @ symmetry_elements(symmetry):
        truth = _project(K, points @ pose[:3, :3].T + pose[:3, 3])
        best = min(best, float(np.max(np.linalg.norm(seen - truth, axis=1))))
    return best


@lru_cache(maxsize=32)
def _scene(vertices: bytes, triangles: bytes) -> o3d.t.geometry.RaycastingScene:
    """A ray-casting scene of one mesh (its vertices and triangles as bytes), kept for
    the next renderings of the same model."""
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(
        o3d.core.Tensor(np.frombuffer(vertices, dtype=np.float32).reshape(-1, 3)),
        o3d.core.Tensor(np.frombuffer(triangles, dtype=np.uint32).reshape(-1, 3)),
    )
    return scene


def _window(
    mesh: o3d.geometry.TriangleMesh, T: np.ndarray, K: np.ndarray, shape: tuple[int, int]
) -> tuple[int, int, int, int]:
    """Rows and columns ``(v0, v1, u0, u1)`` (half-open) holding the posed mesh's image:
    its vertices' pixels and one pixel more; the whole image when a vertex is not in
    front of the camera."""
    vertices = np.asarray(mesh.vertices) @ T[:3, :3].T + T[:3, 3]
    height, width = shape
    if len(vertices) == 0 or np.any(vertices[:, 2] <= 1e-9):
        return 0, height, 0, width
    pixels = _project(K, vertices)
    u0, v0 = np.floor(pixels.min(axis=0)).astype(int) - 1
    u1, v1 = np.ceil(pixels.max(axis=0)).astype(int) + 2
    return max(v0, 0), min(v1, height), max(u0, 0), min(u1, width)


def render_depth(
    mesh: o3d.geometry.TriangleMesh, T: np.ndarray, K: np.ndarray, shape: tuple[int, int]
) -> np.ndarray:
    """The depth image (z, metres; 0 where the ray misses) of ``mesh`` posed by ``T``.

    Parameters
    ----------
    mesh : open3d.geometry.TriangleMesh
        The model (m), in its own frame.
    T : ndarray, shape (4, 4)
        Model-to-camera pose.
    K : ndarray, shape (3, 3)
        Intrinsics (pixels).
    shape : (int, int)
        Image height and width (pixels).

    Returns
    -------
    ndarray, shape (height, width), float64
    """
    T = np.asarray(T, dtype=np.float64)
    K = np.asarray(K, dtype=np.float64)
    depth = np.zeros(shape, dtype=np.float64)
    v0, v1, u0, u1 = _window(mesh, T, K, shape)
    if v0 >= v1 or u0 >= u1:
        return depth
    scene = _scene(
        np.asarray(mesh.vertices, dtype=np.float32).tobytes(),
        np.asarray(mesh.triangles, dtype=np.uint32).tobytes(),
    )
    u, v = np.meshgrid(np.arange(u0, u1), np.arange(v0, v1))
    pixels = np.stack([u.ravel(), v.ravel(), np.ones(u.size)], axis=1)
    directions = pixels @ np.linalg.inv(K).T  # z = 1: the ray parameter is the depth
    # Cast in the model's frame: camera centre and directions moved by T^-1.
    rotation, translation = T[:3, :3], T[:3, 3]
    origin = -rotation.T @ translation
    rays = np.concatenate(
        [np.broadcast_to(origin, directions.shape), directions @ rotation], axis=1
    ).astype(np.float32)
    hit = scene.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy().astype(np.float64)
    hit[~np.isfinite(hit)] = 0.0
    depth[v0:v1, u0:u1] = hit.reshape(v1 - v0, u1 - u0)
    return depth


def _distance_image(depth: np.ndarray, K: np.ndarray) -> np.ndarray:
    """Depth (z) turned into the distance from the camera centre along each pixel's ray."""
    height, width = depth.shape
    u, v = np.meshgrid(np.arange(width), np.arange(height))
    K = np.asarray(K, dtype=np.float64)
    x = (u - K[0, 2]) / K[0, 0]
    y = (v - K[1, 2]) / K[1, 1]
    return depth * np.sqrt(x**2 + y**2 + 1.0)


def _visible(test: np.ndarray, model: np.ndarray, delta: float) -> np.ndarray:
    """BOP 2019's visibility mask: the model's surface is rendered there and not behind
    the test surface by more than ``delta`` (or the test image has no depth there)."""
    return (model > 0) & ((model - test <= delta) | (test == 0))


def vsd(
    T_est: np.ndarray,
    T_gt: np.ndarray,
    mesh: o3d.geometry.TriangleMesh,
    depth_test: np.ndarray,
    K: np.ndarray,
    diameter: float,
    *,
    delta: float = VSD_DELTA_M,
    taus: tuple[float, ...] = VSD_TAUS,
) -> np.ndarray:
    """Visible surface discrepancy of an estimate, one value per ``tau``.

    Parameters
    ----------
    T_est, T_gt : ndarray, shape (4, 4)
        Model-to-camera poses.
    mesh : open3d.geometry.TriangleMesh
        The model's surface (m).
    depth_test : ndarray, shape (H, W)
        The test depth image (z, metres; 0 where the sensor gave none).
    K : ndarray, shape (3, 3)
        Intrinsics (pixels).
    diameter : float
        The object's diameter (m); ``taus`` are fractions of it.
    delta : float, optional
        Tolerance of the visibility test (m).
    taus : tuple of float, optional
        Misalignment tolerances, fractions of ``diameter``.

    Returns
    -------
    ndarray, shape (len(taus),), float64
        Errors in [0, 1]; 1 when neither pose shows any of the model.
    """
    depth_test = np.asarray(depth_test, dtype=np.float64)
    if depth_test.ndim != 2:
        raise ValueError(f"depth_test must be an (H, W) image, got shape {depth_test.shape}")
    if not diameter > 0:
        raise ValueError(f"diameter must be positive (m), got {diameter}")
    shape = depth_test.shape
    est = _distance_image(render_depth(mesh, T_est, K, shape), K)
    gt = _distance_image(render_depth(mesh, T_gt, K, shape), K)
    test = _distance_image(depth_test, K)
    visible_gt = _visible(test, gt, delta)
    visible_est = _visible(test, est, delta) | (visible_gt & (est > 0))
    inter = visible_gt & visible_est
    union = int(np.count_nonzero(visible_gt | visible_est))
    if union == 0:
        return np.ones(len(taus))
    unmatched = union - int(np.count_nonzero(inter))
    gaps = np.abs(gt[inter] - est[inter]) / diameter
    return np.array([(np.count_nonzero(gaps >= tau) + unmatched) / union for tau in taus])


def _recall(errors: np.ndarray, thresholds: np.ndarray) -> float:
    """Share of correct estimates (error below the threshold; NaN: wrong), averaged over
    the thresholds; NaN for no estimates."""
    errors = np.asarray(errors, dtype=np.float64)
    if errors.size == 0:
        return float("nan")
    with np.errstate(invalid="ignore"):  # NaN compares False: a missing estimate is wrong
        return float(np.mean(errors[..., None] < np.asarray(thresholds)))


def vsd_recall(errors: np.ndarray, thresholds: tuple[float, ...] = VSD_THRESHOLDS) -> float:
    """VSD recall: share of the (estimate, tau, threshold) triples with error below the
    threshold. ``errors`` has shape (N, len(VSD_TAUS)); a row of NaN is a missing
    estimate."""
    errors = np.asarray(errors, dtype=np.float64)
    if errors.ndim != 2:
        raise ValueError(f"errors must have shape (N, taus), got {errors.shape}")
    return _recall(errors, np.asarray(thresholds))


def mssd_recall(
    errors_m: np.ndarray, diameters_m: np.ndarray, thresholds: tuple[float, ...] = MSSD_THRESHOLDS
) -> float:
    """MSSD recall of errors (N,) in metres against thresholds in diameters (N,)."""
    scaled = np.asarray(errors_m, dtype=np.float64) / np.asarray(diameters_m, dtype=np.float64)
    return _recall(scaled, np.asarray(thresholds))


def mspd_recall(
    errors_px: np.ndarray,
    widths_px: np.ndarray,
    thresholds: tuple[float, ...] = MSPD_THRESHOLDS_PX,
) -> float:
    """MSPD recall of errors (N,) in pixels; the thresholds scale with each image's width
    (N,) over 640 pixels."""
    scaled = np.asarray(errors_px, dtype=np.float64) * 640.0 / np.asarray(widths_px, dtype=float)
    return _recall(scaled, np.asarray(thresholds))


def average_recall(vsd: float, mssd: float, mspd: float) -> float:
    """BOP's AR: the mean of the three recalls."""
    return float(np.mean([vsd, mssd, mspd]))
