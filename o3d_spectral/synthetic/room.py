"""A furnished room scanned as 3DMatch-style fragments: the registration problem of a user
who fuses depth frames in short runs and must join the runs without their poses.

:func:`room_meshes` builds a room (floor, four walls, cabinets and frames along the walls,
tables with bundled models on them, boxes, chairs and lamps on the floor).
:func:`room_fragments` moves a depth camera round the room's centre, looking out at the
walls: each fragment fuses a few consecutive depth frames
(:mod:`o3d_spectral.synthetic.camera`, Kinect-like noise) and is read one point per cube
of ``spacing``, in the frame of its first camera, without normals, as the
geometric-registration benchmark's fragments are. Fragments a few turns apart share part
of the room; :func:`fragment_pairs` lists the pairs that share enough of it, with the
transformation that takes one onto the other.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
import open3d as o3d
from scipy.spatial import cKDTree

from o3d_spectral.synthetic.camera import look_at, scan_meshes
from o3d_spectral.synthetic.models import model_names
from o3d_spectral.synthetic.sampling import rigid, transform_points
from o3d_spectral.synthetic.sensor import CameraIntrinsics, DepthNoise
from o3d_spectral.synthetic.tabletop import table_mesh, tabletop

__all__ = ["RoomOptions", "Fragment", "room_meshes", "room_fragments", "fragment_pairs"]


@dataclass(frozen=True)
class RoomOptions:
    """The room and the camera's run round it.

    Attributes
    ----------
    size : (float, float, float), default (4.6, 3.8, 2.6)
        The room's length, width and height, metres.
    cabinets : int, default 8
        Boxes 0.4-1.4 m wide standing against the walls.
    frames : int, default 8
        Thin boxes (pictures, shelves) hung on the walls 0.9-2 m up.
    tables : int, default 3
        Tables (0.8 x 0.6 m, 0.75 m high) with three bundled models each.
    clutter : int, default 14
        Things standing on the floor between the camera's run and the walls: boxes,
        chairs and floor lamps, at random places and headings.
    fragments : int, default 12
        Fragments, their first cameras evenly spread over a full turn.
    frames_per_fragment : int, default 5
        Depth frames fused into a fragment.
    frame_step : float, default 6.0
        Degrees the camera turns between two frames of a fragment.
    spacing : float, default 0.01
        A fragment keeps one point per cube of this many metres.
    """

    size: tuple[float, float, float] = (4.6, 3.8, 2.6)
    cabinets: int = 8
    frames: int = 8
    tables: int = 3
    clutter: int = 14
    fragments: int = 12
    frames_per_fragment: int = 5
    frame_step: float = 6.0
    spacing: float = 0.01


@dataclass(frozen=True)
class Fragment:
    """One fragment: ``points`` (N, 3), metres, in the frame of its first camera, whose
    pose in the room is ``world_from_fragment`` (4, 4)."""

    points: np.ndarray
    world_from_fragment: np.ndarray


def _yawed(yaw: float, at: np.ndarray) -> np.ndarray:
    """The 4x4 pose turned ``yaw`` radians about the vertical and moved to ``at`` (3,)."""
    c, s = np.cos(yaw), np.sin(yaw)
    return rigid(np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]), at)


def _box(extent: np.ndarray, centre: np.ndarray, yaw: float = 0.0) -> o3d.geometry.TriangleMesh:
    """A box of ``extent`` (3,) metres centred on ``centre`` (3,), turned ``yaw`` radians
    about the vertical."""
    box = o3d.geometry.TriangleMesh.create_box(*extent).translate(-0.5 * np.asarray(extent))
    return box.transform(_yawed(yaw, centre))


def _against_wall(
    size: np.ndarray, depth: float, rng: np.random.Generator,
) -> tuple[np.ndarray, float]:
    """A point along a random wall, ``depth`` metres in from it (x, y), and the yaw
    (radians) that turns a box's x axis along that wall."""
    wall = int(rng.integers(4))
    half = size[:2] / 2
    along = rng.uniform(-0.8, 0.8) * half[(wall + 1) % 2]
    inward = half[wall % 2] - depth
    sign = 1.0 if wall < 2 else -1.0
    xy = np.array([sign * inward, along]) if wall % 2 == 0 else np.array([along, sign * inward])
    return xy, (np.pi / 2 if wall % 2 == 0 else 0.0)


def _chair(yaw: float, xy: np.ndarray) -> list[o3d.geometry.TriangleMesh]:
    """A chair (seat 0.45 m up, back 0.9 m) at ``xy`` (metres) facing ``yaw`` radians."""
    turn = _yawed(yaw, np.array([*xy, 0.0]))
    parts = [_box(np.array([0.45, 0.45, 0.05]), np.array([0.0, 0.0, 0.45])),
             _box(np.array([0.05, 0.45, 0.45]), np.array([-0.2, 0.0, 0.7]))]
    parts += [_box(np.array([0.04, 0.04, 0.43]), np.array([x, y, 0.215]))
              for x in (-0.2, 0.2) for y in (-0.2, 0.2)]
    return [part.transform(turn) for part in parts]


def _lamp(xy: np.ndarray) -> list[o3d.geometry.TriangleMesh]:
    """A floor lamp at ``xy`` (metres): a pole 1.5 m high under a shade."""
    pole = o3d.geometry.TriangleMesh.create_cylinder(radius=0.02, height=1.5)
    shade = o3d.geometry.TriangleMesh.create_cone(radius=0.22, height=0.3)
    return [pole.translate([*xy, 0.75]), shade.translate([*xy, 1.35])]


def _clutter(size: np.ndarray, rng: np.random.Generator) -> list[o3d.geometry.TriangleMesh]:
    """One thing on the floor (a box, a chair or a lamp) 1-2 m from the room's centre and
    at least 0.3 m from the walls."""
    half = size[:2] / 2 - 0.3
    while True:
        xy = rng.uniform(-half, half)
        if 1.0 <= np.linalg.norm(xy) <= 2.0:
            break
    kind, yaw = int(rng.integers(3)), rng.uniform(0.0, 2 * np.pi)
    if kind == 0:
        extent = rng.uniform(0.15, 0.7, size=3)
        return [_box(extent, np.array([*xy, extent[2] / 2]), yaw)]
    return _chair(yaw, xy) if kind == 1 else _lamp(xy)


def room_meshes(options: RoomOptions, rng: np.random.Generator) -> list[o3d.geometry.TriangleMesh]:
    """The room of ``options`` (world frame, metres; the floor is z = 0, the room centred
    on the vertical axis): floor, walls, cabinets, frames, tables with models and the
    clutter on the floor."""
    size = np.asarray(options.size, dtype=float)
    wall = 0.1
    meshes = [_box(np.array([size[0], size[1], wall]), np.array([0.0, 0.0, -wall / 2]))]
    for axis in (0, 1):
        for sign in (-1.0, 1.0):
            extent = np.array([wall, size[1], size[2]]) if axis == 0 else np.array(
                [size[0], wall, size[2]])
            centre = np.zeros(3)
            centre[axis], centre[2] = sign * (size[axis] + wall) / 2, size[2] / 2
            meshes.append(_box(extent, centre))
    for _ in range(options.cabinets):
        extent = rng.uniform([0.4, 0.35, 0.4], [1.4, 0.7, 1.9])
        xy, yaw = _against_wall(size, extent[1] / 2, rng)
        meshes.append(_box(extent, np.array([*xy, extent[2] / 2]), yaw))
    for _ in range(options.frames):
        extent = np.array([rng.uniform(0.3, 1.0), 0.04, rng.uniform(0.2, 0.7)])
        xy, yaw = _against_wall(size, 0.02, rng)
        meshes.append(_box(extent, np.array([*xy, rng.uniform(0.9, 2.0)]), yaw))
    names = model_names()
    for _ in range(options.tables):
        angle, reach = rng.uniform(0.0, 2 * np.pi), rng.uniform(1.1, 1.4)
        placed = rigid(np.eye(3), np.array([reach * np.cos(angle), reach * np.sin(angle), 0.75]))
        chosen = [str(n) for n in rng.choice(names, size=3, replace=False)]
        _, _, models = tabletop(chosen, rng, cluster=False)
        legs = [_box(np.array([0.04, 0.04, 0.72]), np.array([x, y, -0.39]))
                for x in (-0.36, 0.36) for y in (-0.26, 0.26)]
        meshes += [m.transform(placed) for m in (table_mesh(), *legs, *models)]
    for _ in range(options.clutter):
        meshes += _clutter(size, rng)
    return meshes


def _camera(degrees: float) -> np.ndarray:
    """The camera's pose (world from camera) ``degrees`` round its run: 0.4 m from the
    room's centre, 1.5 m up, looking out and a little down."""
    a = np.deg2rad(degrees)
    out = np.array([np.cos(a), np.sin(a), 0.0])
    eye = 0.4 * out + np.array([0.0, 0.0, 1.5])
    return look_at(eye, eye + 2.0 * out - np.array([0.0, 0.0, 0.6]))


def room_fragments(options: RoomOptions, seed: int) -> list[Fragment]:
    """The fragments of one room drawn from ``seed`` (:class:`RoomOptions`)."""
    rng = np.random.default_rng(seed)
    meshes = room_meshes(options, rng)
    intrinsics, noise = CameraIntrinsics(), DepthNoise(max_depth=4.0)
    fragments = []
    for k in range(options.fragments):
        start = 360.0 * k / options.fragments
        first = _camera(start)
        to_first = np.linalg.inv(first)
        parts = []
        for f in range(options.frames_per_fragment):
            camera = _camera(start + f * options.frame_step)
            scan = scan_meshes(meshes, intrinsics, camera, noise=noise, rng=rng)
            parts.append(transform_points(to_first @ camera, scan.points))
        cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.concatenate(parts)))
        points = np.asarray(cloud.voxel_down_sample(options.spacing).points)
        fragments.append(Fragment(points, first))
    return fragments


def fragment_pairs(
    fragments: list[Fragment], overlap: float = 0.3, distance: float = 0.05,
) -> dict[tuple[int, int], np.ndarray]:
    """The pairs ``(i, j)``, ``i < j``, whose overlap exceeds ``overlap``: the share of
    the smaller fragment's points within ``distance`` metres of the other's, placed by
    the truth (the geometric-registration benchmark's rule, 30%). Each maps to the 4x4
    transformation that takes fragment ``j`` onto fragment ``i`` (``gt.log``'s)."""
    trees = [cKDTree(f.points) for f in fragments]  # one a fragment, in its own frame
    pairs = {}
    for i, j in itertools.combinations(range(len(fragments)), 2):
        a, b = fragments[i], fragments[j]
        T = np.linalg.inv(a.world_from_fragment) @ b.world_from_fragment
        if len(b.points) <= len(a.points):  # the smaller's points, near the larger's
            near, _ = trees[i].query(transform_points(T, b.points), distance_upper_bound=distance)
        else:
            near, _ = trees[j].query(transform_points(np.linalg.inv(T), a.points),
                                     distance_upper_bound=distance)
        if np.mean(np.isfinite(near)) > overlap:
            pairs[(i, j)] = T
    return pairs
