"""The support table and bundled models resting on it without interpenetration (world
frame: the table top is the plane z = 0; metres). Used by the ``cluttered`` scenes and by
the servoing scene (:mod:`o3d_spectral.servo.scene`)."""

from __future__ import annotations

from functools import cache

import numpy as np
import open3d as o3d
from scipy.spatial.transform import Rotation

from o3d_spectral.synthetic.instance import MAX_TRIES
from o3d_spectral.synthetic.sampling import model_mesh, moved, rigid
from o3d_spectral.synthetic.symmetry import surface_moments

__all__ = ["table_mesh", "tabletop"]

_TABLE_SIZE = (0.8, 0.6)  # m
_CLUSTER = 0.15  # m, half-size of the square around the first object tried first
_CELL = 0.005  # m, footprint grid
_NEIGHBOURS = np.array([(i, j) for i in (-1, 0, 1) for j in (-1, 0, 1)])


@cache
def _principal_axes(name: str) -> np.ndarray:
    return surface_moments(model_mesh(name))[1]


def _resting_pose(name: str, rng: np.random.Generator) -> np.ndarray:
    """Rotation (3x3) resting model ``name`` on one of the six faces of its principal box,
    random yaw: a principal axis (random sign) is turned to point down."""
    axes = _principal_axes(name)
    down = axes[:, rng.integers(3)] * rng.choice([-1.0, 1.0])
    # Rotation taking `down` to -z, then a yaw about z.
    align, _ = Rotation.align_vectors([[0.0, 0.0, -1.0]], [down])
    yaw = Rotation.from_rotvec([0.0, 0.0, rng.uniform(0, 2 * np.pi)])
    return (yaw * align).as_matrix()


def place_on_table(
    names: list[str], rng: np.random.Generator, size: tuple[float, float] = _TABLE_SIZE,
    *, cluster: bool = True,
) -> tuple[list[str], list[np.ndarray]]:
    """World-from-model poses of objects resting on the table top (z = 0) without overlap.

    Each object's footprint is the set of 5 mm grid cells holding its vertices' ground
    projections (the meshes are dense enough for this to cover the silhouette); a new object
    may not touch an occupied cell or its 8 neighbours, so objects never interpenetrate.
    The first object goes anywhere in the table's central half; with ``cluster`` the others
    are tried near it first (within 15 cm, for clutter), then anywhere; objects that still
    do not fit are left out (the first one always fits). ``size``: the table's (x, y)
    extent, metres.
    """
    shape = np.ceil(np.array(size) / _CELL).astype(int)
    occupied = np.zeros(shape, dtype=bool)
    half = np.array(size) / 2
    placed_names, poses, first_xy = [], [], np.zeros(2)
    for name in names:
        vertices = np.asarray(model_mesh(name).vertices)
        for attempt in range(MAX_TRIES):
            rotation = _resting_pose(name, rng)
            rotated = vertices @ rotation.T
            center_xy = 0.5 * (rotated[:, :2].min(axis=0) + rotated[:, :2].max(axis=0))
            if not poses:
                xy = rng.uniform(-half / 2, half / 2)
            elif cluster and attempt < MAX_TRIES // 2:
                xy = first_xy + rng.uniform(-_CLUSTER, _CLUSTER, size=2)
            else:
                xy = rng.uniform(-half, half)
            cells = np.floor((rotated[:, :2] - center_xy + xy + half) / _CELL).astype(int)
            if np.any(cells < 1) or np.any(cells >= shape - 1):
                continue  # off the table
            grown = (cells[:, None, :] + _NEIGHBOURS[None]).reshape(-1, 2)
            if occupied[grown[:, 0], grown[:, 1]].any():
                continue
            occupied[cells[:, 0], cells[:, 1]] = True
            if not poses:
                first_xy = xy
            placed_names.append(name)
            poses.append(rigid(rotation, np.append(xy - center_xy, -rotated[:, 2].min())))
            break
    return placed_names, poses


def table_mesh(size: tuple[float, float] = _TABLE_SIZE) -> o3d.geometry.TriangleMesh:
    """The support table: a 3 cm slab of ``size`` (x, y; metres) whose top face is the
    plane z = 0, centred on the origin (world frame, metres)."""
    table = o3d.geometry.TriangleMesh.create_box(*size, 0.03)
    table.translate([-size[0] / 2, -size[1] / 2, -0.03])
    table.compute_triangle_normals()
    return table


def tabletop(
    names: list[str], rng: np.random.Generator, size: tuple[float, float] = _TABLE_SIZE,
    *, cluster: bool = True,
) -> tuple[list[str], list[np.ndarray], list[o3d.geometry.TriangleMesh]]:
    """Bundled models resting on :func:`table_mesh` without interpenetration.

    Parameters
    ----------
    names : list of str
        Models to place, the first near the table's centre, the others around it
        (``cluster``) or anywhere on it.
    rng : numpy.random.Generator
    size : (float, float)
        The table's extent (x, y), metres.
    cluster : bool
        Try the other objects within 15 cm of the first before anywhere else.

    Returns
    -------
    placed : list of str
        The models that fit (the first always does).
    poses : list of ndarray, shape (4, 4)
        Their world-from-model poses.
    meshes : list of open3d.geometry.TriangleMesh
        The models moved to those poses (world frame, metres).
    """
    placed, poses = place_on_table(names, rng, size, cluster=cluster)
    return placed, poses, [moved(model_mesh(n), p) for n, p in zip(placed, poses, strict=True)]
