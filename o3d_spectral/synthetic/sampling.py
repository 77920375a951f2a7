"""Random samples the scene generator draws: model clouds, surface points, directions and
rotations; and the small rigid-motion helpers the scene modules share (metres, radians)."""

from __future__ import annotations

from functools import cache

import numpy as np
import open3d as o3d
from scipy.spatial.transform import Rotation

from o3d_spectral.synthetic.models import load_model

__all__ = [
    "model_cloud",
    "model_mesh",
    "moved",
    "point_cloud",
    "random_direction",
    "rigid",
    "sample_rotation",
    "sample_surface",
    "transform_points",
]

_MODEL_SEED = 20240601  # fixed: a model's source cloud is the same in every suite


@cache
def model_mesh(name: str) -> o3d.geometry.TriangleMesh:
    """The bundled mesh, loaded once per process; never modify it (see ``moved``)."""
    return load_model(name)


@cache
def model_cloud(name: str, n_points: int) -> tuple[np.ndarray, np.ndarray]:
    """Poisson-disk samples of model ``name`` with outward normals, in the mesh frame.

    Seeded with a fixed seed, so a model's cloud is the same everywhere; cached.

    Returns
    -------
    points, normals : ndarray, shape (n_points, 3), float64
        Read-only arrays (m, unit normals).
    """
    mesh = model_mesh(name)
    o3d.utility.random.seed(_MODEL_SEED)
    cloud = mesh.sample_points_poisson_disk(n_points, init_factor=5)
    points, normals = np.asarray(cloud.points).copy(), np.asarray(cloud.normals).copy()
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    points.flags.writeable = False
    normals.flags.writeable = False
    return points, normals


def sample_surface(
    mesh: o3d.geometry.TriangleMesh, n_points: int, *, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Area-uniform random points (m) and interpolated vertex normals on ``mesh``, (N, 3)."""
    v, t = np.asarray(mesh.vertices), np.asarray(mesh.triangles)
    vn = np.asarray(mesh.vertex_normals)
    area = 0.5 * np.linalg.norm(np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]]), axis=1)
    tri = t[rng.choice(len(t), size=n_points, p=area / area.sum())]
    r1, r2 = np.sqrt(rng.random(n_points)), rng.random(n_points)
    w = np.stack([1 - r1, r1 * (1 - r2), r1 * r2], axis=1)  # uniform barycentric weights
    points = np.einsum("nk,nkd->nd", w, v[tri])
    normals = np.einsum("nk,nkd->nd", w, vn[tri])
    return points, normals / np.linalg.norm(normals, axis=1, keepdims=True)


def random_direction(rng: np.random.Generator) -> np.ndarray:
    """A unit 3-vector uniform on the sphere."""
    d = rng.standard_normal(3)
    return d / np.linalg.norm(d)


def sample_rotation(
    rng: np.random.Generator, *, angle_range: tuple[float, float] | None = None
) -> np.ndarray:
    """A random 3x3 rotation: Haar-uniform on SO(3), or uniform axis and angle in range.

    Parameters
    ----------
    rng : numpy.random.Generator
        Randomness.
    angle_range : (float, float), optional
        ``(min, max)`` rotation angle in radians; the angle is uniform in the range (not
        Haar-distributed), as wanted for success-versus-angle curves.
    """
    if angle_range is None:
        return Rotation.random(random_state=rng).as_matrix()
    angle = rng.uniform(*angle_range)
    return Rotation.from_rotvec(angle * random_direction(rng)).as_matrix()


def transform_points(matrix: np.ndarray, points: np.ndarray) -> np.ndarray:
    return points @ matrix[:3, :3].T + matrix[:3, 3]


def point_cloud(points: np.ndarray, normals: np.ndarray) -> o3d.geometry.PointCloud:
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    cloud.normals = o3d.utility.Vector3dVector(normals)
    return cloud


def rigid(rotation: np.ndarray, translation: np.ndarray) -> np.ndarray:
    matrix = np.eye(4)
    matrix[:3, :3], matrix[:3, 3] = rotation, translation
    return matrix



def moved(mesh: o3d.geometry.TriangleMesh, matrix: np.ndarray) -> o3d.geometry.TriangleMesh:
    out = o3d.geometry.TriangleMesh(mesh)
    out.transform(matrix)
    return out

