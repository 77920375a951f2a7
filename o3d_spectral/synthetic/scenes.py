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

from dataclasses import dataclass, field
from functools import cache

import numpy as np
import open3d as o3d
from scipy.spatial.transform import Rotation

from o3d_spectral.symmetry import Symmetry, model_symmetry, surface_moments
from o3d_spectral.synthetic.camera import (
    CameraIntrinsics,
    DepthNoise,
    RenderedView,
    hit_labels,
    look_at,
    render,
    scan_from_view,
)
from o3d_spectral.synthetic.models import load_model, model_names

__all__ = [
    "CONDITIONS",
    "Instance",
    "SceneOptions",
    "make_instance",
    "model_cloud",
    "sample_rotation",
    "table_mesh",
    "tabletop",
]

CONDITIONS: tuple[str, ...] = ("full", "partial", "occluded", "cluttered")

#: Label of table and occluder points in ``Instance.target_labels``.
BACKGROUND = -1

_MODEL_SEED = 20240601  # fixed: a model's source cloud is the same in every suite
_MAX_TRIES = 200


@dataclass(frozen=True)
class SceneOptions:
    """Settings of the scene generator (units: metres, radians).

    Parameters
    ----------
    intrinsics : CameraIntrinsics
        The virtual camera (default 640x480, 60 degrees wide).
    noise : DepthNoise
        Sensor model of the scans.
    source_points : int
        Points of the source (Poisson-disk samples of the model mesh).
    full_noise_sigma : float
        Standard deviation (m) of the isotropic Gaussian noise on the ``full`` target.
    angle_range : (float, float) or None
        Initial rotation angle range (radians) in [0, pi]; None draws uniformly over SO(3).
    max_offset : float
        Upper bound (m) of the initial displacement of the object centroid.
    distance_range : (float, float)
        Camera-to-object distance (m) in ``partial`` and ``occluded``.
    occlusion_range : (float, float)
        Range of the requested occlusion fraction in ``occluded``.
    clutter_objects : (int, int)
        Inclusive range of the number of objects on the table in ``cluttered``.
    min_visible : float
        ``cluttered``: least share of the chosen object's pixels that other objects may
        leave visible (``1 - occlusion``).
    """

    intrinsics: CameraIntrinsics = field(default_factory=CameraIntrinsics)
    noise: DepthNoise = field(default_factory=DepthNoise)
    source_points: int = 3000
    full_noise_sigma: float = 0.001
    angle_range: tuple[float, float] | None = None
    max_offset: float = 0.1
    distance_range: tuple[float, float] = (0.4, 1.0)
    occlusion_range: tuple[float, float] = (0.2, 0.7)
    clutter_objects: tuple[int, int] = (3, 8)
    min_visible: float = 0.3

    def __post_init__(self) -> None:
        if self.source_points < 100:
            raise ValueError(f"source_points must be >= 100, got {self.source_points}")
        if self.angle_range is not None:
            lo, hi = self.angle_range
            if not 0 <= lo <= hi <= np.pi:
                raise ValueError(
                    f"angle_range must satisfy 0 <= min <= max <= pi (radians), got "
                    f"{self.angle_range}"
                )
        if self.max_offset < 0:
            raise ValueError(f"max_offset must be >= 0 m, got {self.max_offset}")
        if not 0 < self.distance_range[0] <= self.distance_range[1]:
            raise ValueError(f"distance_range must be 0 < min <= max, got {self.distance_range}")
        if not 0 <= self.occlusion_range[0] <= self.occlusion_range[1] < 1:
            raise ValueError(
                f"occlusion_range must satisfy 0 <= min <= max < 1, got {self.occlusion_range}"
            )
        if not 1 <= self.clutter_objects[0] <= self.clutter_objects[1] <= len(model_names()):
            raise ValueError(f"clutter_objects must be 1 <= min <= max, got {self.clutter_objects}")
        if not 0 < self.min_visible <= 1:
            raise ValueError(f"min_visible must be in (0, 1], got {self.min_visible}")


@dataclass
class Instance:
    """One registration problem.

    Attributes
    ----------
    source : open3d.geometry.PointCloud
        Object model points with outward normals, in the source frame (m).
    target : open3d.geometry.PointCloud
        The observation (m): for scans, camera frame with normals facing the camera.
    T_gt : ndarray, shape (4, 4), float64
        Ground truth, ``target ~ T_gt @ source`` on the object's points.
    target_labels : ndarray, shape (M,), int
        Per target point: index into ``metadata["scene_objects"]`` (0 is the object of
        ``source``), or -1 for table and occluder points.
    source_from_model : ndarray, shape (4, 4), float64
        Pose of the model mesh in the source frame: ``source = source_from_model @ mesh``.
    metadata : dict
        JSON-serialisable description (see ``docs/suites.md``).
    """

    source: o3d.geometry.PointCloud
    target: o3d.geometry.PointCloud
    T_gt: np.ndarray
    target_labels: np.ndarray
    source_from_model: np.ndarray
    metadata: dict

    @property
    def object(self) -> str:
        """Name of the model in ``source``."""
        return self.metadata["object"]

    @property
    def source_center(self) -> np.ndarray:
        """Centroid of the source points (m), shape (3,): where translation errors are
        measured (:func:`o3d_spectral.symmetry.translation_error`'s ``center``)."""
        return np.asarray(self.source.points).mean(axis=0)

    @property
    def symmetry(self) -> Symmetry:
        """Symmetry group of the object, expressed in the source frame."""
        return model_symmetry(self.object).transformed(self.source_from_model)


# --- sampling helpers -------------------------------------------------------------------


@cache
def _mesh(name: str) -> o3d.geometry.TriangleMesh:
    """The bundled mesh, loaded once per process; never modify it (see ``_moved``)."""
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
    mesh = _mesh(name)
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


def _transform(matrix: np.ndarray, points: np.ndarray) -> np.ndarray:
    return points @ matrix[:3, :3].T + matrix[:3, 3]


def _cloud(points: np.ndarray, normals: np.ndarray) -> o3d.geometry.PointCloud:
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    cloud.normals = o3d.utility.Vector3dVector(normals)
    return cloud


def _rigid(rotation: np.ndarray, translation: np.ndarray) -> np.ndarray:
    matrix = np.eye(4)
    matrix[:3, :3], matrix[:3, 3] = rotation, translation
    return matrix


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
    center_target = _transform(target_from_model, points.mean(axis=0, keepdims=True))[0]
    center_source = center_target - offset
    t_gt = _rigid(rotation, center_target - rotation @ center_source)
    source_from_model = np.linalg.inv(t_gt) @ target_from_model
    source = _cloud(_transform(source_from_model, points), normals @ source_from_model[:3, :3].T)
    info = {
        "init_angle_deg": float(np.rad2deg(Rotation.from_matrix(rotation).magnitude())),
        "init_offset_m": float(np.linalg.norm(offset)),
    }
    return source, t_gt, source_from_model, info


def _visible_fraction(model_points: np.ndarray, view: RenderedView, label: int) -> float:
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


def _in_image(
    mesh: o3d.geometry.TriangleMesh, camera_from_world: np.ndarray, intr: CameraIntrinsics
) -> bool:
    """True if all vertices of world-frame ``mesh`` project inside the image, in front."""
    points = _transform(camera_from_world, np.asarray(mesh.vertices))
    uv = intr.project(points)
    return bool(
        np.all(points[:, 2] > 0) and np.all((uv >= 0) & (uv <= [intr.width - 1, intr.height - 1]))
    )


def _object_pixels(
    mesh: o3d.geometry.TriangleMesh, world_from_camera: np.ndarray, intr: CameraIntrinsics
) -> np.ndarray:
    """``(row, column)`` pixels (N, 2) where world-frame ``mesh``, alone, is seen; only the
    mesh's projected bounding box is cast."""
    uv = intr.project(_transform(np.linalg.inv(world_from_camera), np.asarray(mesh.vertices)))
    lo = np.clip(np.floor(uv.min(axis=0)).astype(int), 0, None)
    hi = np.minimum(np.ceil(uv.max(axis=0)).astype(int), [intr.width - 1, intr.height - 1])
    cols, rows = np.meshgrid(np.arange(lo[0], hi[0] + 1), np.arange(lo[1], hi[1] + 1))
    pixels = np.stack([rows.ravel(), cols.ravel()], axis=1)
    return pixels[hit_labels([mesh], intr, world_from_camera, pixels=pixels) == 0]


def _moved(mesh: o3d.geometry.TriangleMesh, matrix: np.ndarray) -> o3d.geometry.TriangleMesh:
    out = o3d.geometry.TriangleMesh(mesh)
    out.transform(matrix)
    return out


def _scan_metadata(view_pose: np.ndarray, distance: float) -> dict:
    return {"world_from_camera": view_pose.tolist(), "camera_distance_m": float(distance)}


# --- conditions ---------------------------------------------------------------------------


def _full(name: str, rng: np.random.Generator, options: SceneOptions) -> Instance:
    mesh = _mesh(name)
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
        _cloud(points, normals),
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
    for _ in range(_MAX_TRIES):
        distance = rng.uniform(*options.distance_range)
        eye = center + distance * random_direction(rng)
        aim = center + rng.uniform(-0.03, 0.03, size=3)
        try:
            pose = look_at(eye, aim, up=random_direction(rng))
        except ValueError:
            continue
        if _in_image(mesh, np.linalg.inv(pose), options.intrinsics):
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
    meta["visible_fraction"] = _visible_fraction(
        _transform(target_from_model, model_points), view, 0
    )
    return Instance(
        source, scan.to_point_cloud(), t_gt, scan.object_ids.copy(), source_from_model, meta
    )


def _partial(name: str, rng: np.random.Generator, options: SceneOptions) -> Instance:
    mesh = _mesh(name)
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


def _panel(size: float) -> o3d.geometry.TriangleMesh:
    """A square board ``size`` wide, 1 cm thick, centred at the origin, normal along z."""
    panel = o3d.geometry.TriangleMesh.create_box(size, size, 0.01)
    panel.translate([-size / 2, -size / 2, -0.005])
    panel.compute_triangle_normals()
    return panel


def _occlusion_of(
    obj: o3d.geometry.TriangleMesh,
    occluder: o3d.geometry.TriangleMesh,
    pose: np.ndarray,
    pixels: np.ndarray,
    intr: CameraIntrinsics,
) -> float:
    """Share of the object's unoccluded ``pixels`` that the occluder hides."""
    labels = hit_labels([obj, occluder], intr, pose, pixels=pixels, labels=[0, BACKGROUND])
    return float(np.mean(labels != 0))


def _place_occluder(
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
    for _ in range(_MAX_TRIES):
        if rng.random() < 0.5:
            kind = str(rng.choice(others))
            shape = _mesh(kind)
            shape = _moved(shape, _rigid(sample_rotation(rng), -shape.get_center()))
        else:
            kind = "panel"
            shape = _moved(_panel(0.6), _rigid(pose[:3, :3], np.zeros(3)))
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
            moved = _moved(shape, _rigid(np.eye(3), anchor + s * slide))
            return _occlusion_of(obj, moved, pose, pixels, options.intrinsics)

        lo, hi = 0.0, radius_obj + radius
        if occlusion(lo) < requested or occlusion(hi) > requested:
            continue
        for _ in range(30):
            mid = 0.5 * (lo + hi)
            value = occlusion(mid)
            if abs(value - requested) <= 0.015:
                return _moved(shape, _rigid(np.eye(3), anchor + mid * slide)), kind, value
            lo, hi = (mid, hi) if value > requested else (lo, mid)
    raise RuntimeError(f"could not occlude {requested:.2f} of {name!r}")


def _occluded(
    name: str, rng: np.random.Generator, options: SceneOptions, occlusion: float | None
) -> Instance:
    mesh = _mesh(name)
    pose, distance = _object_view(mesh, rng, options)
    requested = rng.uniform(*options.occlusion_range) if occlusion is None else occlusion
    pixels = _object_pixels(mesh, pose, options.intrinsics)
    occluder, kind, measured = _place_occluder(mesh, pose, pixels, requested, rng, options, name)
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


_TABLE_SIZE = (0.8, 0.6)  # m
_CLUSTER = 0.15  # m, half-size of the square around the first object tried first
_CELL = 0.005  # m, footprint grid
_NEIGHBOURS = np.array([(i, j) for i in (-1, 0, 1) for j in (-1, 0, 1)])


@cache
def _principal_axes(name: str) -> np.ndarray:
    return surface_moments(_mesh(name))[1]


def _resting_pose(name: str, rng: np.random.Generator) -> np.ndarray:
    """Rotation (3x3) resting model ``name`` on one of the six faces of its principal box,
    random yaw: a principal axis (random sign) is turned to point down."""
    axes = _principal_axes(name)
    down = axes[:, rng.integers(3)] * rng.choice([-1.0, 1.0])
    # Rotation taking `down` to -z, then a yaw about z.
    align, _ = Rotation.align_vectors([[0.0, 0.0, -1.0]], [down])
    yaw = Rotation.from_rotvec([0.0, 0.0, rng.uniform(0, 2 * np.pi)])
    return (yaw * align).as_matrix()


def _place_on_table(
    names: list[str], rng: np.random.Generator
) -> tuple[list[str], list[np.ndarray]]:
    """World-from-model poses of objects resting on the table top (z = 0) without overlap.

    Each object's footprint is the set of 5 mm grid cells holding its vertices' ground
    projections (the meshes are dense enough for this to cover the silhouette); a new object
    may not touch an occupied cell or its 8 neighbours, so objects never interpenetrate.
    The first object goes anywhere in the table's central half; the others are tried near
    it first (within 15 cm, for clutter), then anywhere; objects that still do not fit are
    left out (the first one always fits).
    """
    shape = np.ceil(np.array(_TABLE_SIZE) / _CELL).astype(int)
    occupied = np.zeros(shape, dtype=bool)
    half = np.array(_TABLE_SIZE) / 2
    placed_names, poses, first_xy = [], [], np.zeros(2)
    for name in names:
        vertices = np.asarray(_mesh(name).vertices)
        for attempt in range(_MAX_TRIES):
            rotation = _resting_pose(name, rng)
            rotated = vertices @ rotation.T
            center_xy = 0.5 * (rotated[:, :2].min(axis=0) + rotated[:, :2].max(axis=0))
            if not poses:
                xy = rng.uniform(-half / 2, half / 2)
            elif attempt < _MAX_TRIES // 2:
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
            poses.append(_rigid(rotation, np.append(xy - center_xy, -rotated[:, 2].min())))
            break
    return placed_names, poses


def table_mesh() -> o3d.geometry.TriangleMesh:
    """The support table: a 3 cm slab whose top face is the plane z = 0, centred on the
    origin (world frame, metres)."""
    table = o3d.geometry.TriangleMesh.create_box(*_TABLE_SIZE, 0.03)
    table.translate([-_TABLE_SIZE[0] / 2, -_TABLE_SIZE[1] / 2, -0.03])
    table.compute_triangle_normals()
    return table


def tabletop(
    names: list[str], rng: np.random.Generator
) -> tuple[list[str], list[np.ndarray], list[o3d.geometry.TriangleMesh]]:
    """Bundled models resting on :func:`table_mesh` without interpenetration.

    Parameters
    ----------
    names : list of str
        Models to place, the first near the table's centre, the others around it.
    rng : numpy.random.Generator

    Returns
    -------
    placed : list of str
        The models that fit (the first always does).
    poses : list of ndarray, shape (4, 4)
        Their world-from-model poses.
    meshes : list of open3d.geometry.TriangleMesh
        The models moved to those poses (world frame, metres).
    """
    placed, poses = _place_on_table(names, rng)
    return placed, poses, [_moved(_mesh(n), p) for n, p in zip(placed, poses, strict=True)]


def _cluttered(name: str, rng: np.random.Generator, options: SceneOptions) -> Instance:
    others = [n for n in model_names() if n != name]
    count = int(rng.integers(options.clutter_objects[0], options.clutter_objects[1] + 1))
    chosen = [name] + [str(n) for n in rng.choice(others, size=count - 1, replace=False)]
    names, poses, meshes = tabletop(chosen, rng)
    obj = meshes[0]
    center = np.asarray(obj.get_center())
    # Look across the other objects at the chosen one half of the time, so that it is
    # partly hidden as often as in real clutter; from anywhere the other half.
    across = 0.0
    if len(meshes) > 1:
        toward = np.mean([m.get_center() for m in meshes[1:]], axis=0) - center
        across = float(np.arctan2(toward[1], toward[0]))
    for _ in range(_MAX_TRIES):
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
        if not _in_image(obj, np.linalg.inv(pose), options.intrinsics):
            continue
        alone = _object_pixels(obj, pose, options.intrinsics)
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
            break
    else:
        raise RuntimeError(f"no view sees {name!r} enough; lower min_visible")
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
