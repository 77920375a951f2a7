"""Datasets in the BOP benchmark's layout, as registration instances scored by BOP's metrics.

A BOP dataset folder holds (the BOP toolkit's ``docs/bop_datasets_format.md``)::

    DIR/models_eval/ or DIR/models/    obj_000001.ply, ..., models_info.json
    DIR/<split>/<scene>/               scene_gt.json, scene_camera.json,
                                       scene_gt_info.json (optional), depth/, mask_visib/
    DIR/test_targets_bop19.json        (optional) the targets of the BOP 19+ test split

Lengths in BOP's files are millimetres; here they become metres. VSD renders the surfaces
of ``models/`` (else ``models_eval/``); the registrations' sources, MSSD and MSPD use the
points of ``models_eval/`` (else ``models/``), with their normals (a mesh's vertex
normals; a cloud's own, or estimated and oriented outward); a depth PNG times the image's
``depth_scale`` is depth in millimetres; ``mask_visib/<image>_<k>.png`` marks the pixels
where annotation ``k`` of ``scene_gt.json`` is visible.

Every annotated object of an image (listed in ``test_targets_bop19.json`` on the ``test``
split when the file exists; at least 10% visible when ``scene_gt_info.json`` says) gives
two instances, in two sets: the model against its visible-mask crop (``kind="crop"``) and
the model against the whole depth frame, down-sampled to :data:`FRAME_VOXEL`
(``kind="frame"``). The source is the model's points with their normals; the target
is back-projected depth in the camera frame, normals estimated and turned to the camera;
``T_gt`` is BOP's model-to-camera pose. :meth:`BopSet.score` gives the row's BOP errors.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import numpy as np
import open3d as o3d

from o3d_spectral.harness import pose_metrics
from o3d_spectral.harness.bop_checks import (
    array,
    entry_pose,
    image_id,
    integer,
    listed_targets,
    number,
    visible_fraction,
)
from o3d_spectral.harness.constants import FRAME_VOXEL, MIN_VISIBLE
from o3d_spectral.harness.real import orient_outward
from o3d_spectral.io.files import check_cloud_file
from o3d_spectral.synthetic.instance import Instance
from o3d_spectral.synthetic.symmetry import Symmetry

__all__ = ["FRAME_VOXEL", "KINDS", "MIN_VISIBLE", "BopSet", "symmetry_of",
           "back_project", "read_json"]

#: The two kinds of instance an annotated object gives.
KINDS = ("crop", "frame")
_MM = 1e-3


def read_json(path: Path, what: str) -> object:
    """The JSON document at ``path``; ``FileNotFoundError`` or ``ValueError`` naming the
    file and what it should hold (``what``)."""
    if not path.is_file():
        raise FileNotFoundError(f"no {path.name} at {path} ({what})")
    try:
        return json.loads(path.read_text())
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise ValueError(f"{path} is not valid JSON ({error})") from None


def symmetry_of(info: dict, where: str) -> Symmetry:
    """The symmetry group of a ``models_info.json`` entry, in metres.

    ``symmetries_discrete``: every element but the identity, 4x4 matrices (row-major, 16
    numbers, translation in mm);
    ``symmetries_continuous``: ``{"axis": [3], "offset": [3] (mm)}``, a rotation about the
    line through ``offset`` along ``axis``. One continuous axis at most (``ValueError``
    naming ``where`` otherwise, as for a malformed entry).
    """
    try:
        discrete = [np.asarray(m, dtype=np.float64).reshape(4, 4)
                    for m in info.get("symmetries_discrete", [])]
        continuous = info.get("symmetries_continuous", [])
        for matrix in discrete:
            matrix[:3, 3] *= _MM
        axis = center = None
        if continuous:
            if len(continuous) > 1:
                raise ValueError("more than one continuous axis")
            axis = np.asarray(continuous[0]["axis"], dtype=np.float64).reshape(3)
            axis = axis / np.linalg.norm(axis)
            center = _MM * np.asarray(continuous[0].get("offset", [0, 0, 0]), dtype=float)
    except (TypeError, KeyError, ValueError) as error:
        raise ValueError(f"{where}: bad symmetries ({error})") from None
    group = np.stack([np.eye(4), *discrete])  # BOP lists every element but the identity
    return Symmetry(discrete=group, axis=axis,
                    center=np.zeros(3) if center is None else center)


def back_project(depth: np.ndarray, K: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
    """Camera-frame points (N, 3), metres, of the pixels with depth (and in ``mask``):
    pixel ``(u, v)`` at depth ``z`` is ``z K^-1 (u, v, 1)``.

    Parameters
    ----------
    depth : ndarray, shape (H, W)
        Depth (z) in metres, 0 where there is none.
    K : ndarray, shape (3, 3)
    mask : ndarray of bool, shape (H, W), optional
    """
    chosen = depth > 0 if mask is None else (depth > 0) & mask
    v, u = np.nonzero(chosen)
    z = depth[v, u]
    pixels = np.stack([u * z, v * z, z], axis=1)
    return pixels @ np.linalg.inv(np.asarray(K, dtype=np.float64)).T


def _read_png(path: Path) -> np.ndarray:
    if not path.is_file():
        raise FileNotFoundError(f"no such image: {path}")
    image = np.asarray(o3d.io.read_image(str(path)))
    if image.dtype == object or image.ndim < 2 or image.size == 0:  # an unreadable file
        raise ValueError(f"{path}: Open3D read no pixels from it (a corrupt PNG?)")
    return image


@dataclass(frozen=True)
class _Model:
    points: np.ndarray  # (N, 3) metres
    normals: np.ndarray  # (N, 3)
    mesh: o3d.geometry.TriangleMesh  # metres
    diameter: float  # metres
    symmetry: Symmetry


@dataclass(frozen=True)
class _Target:
    scene: int
    image: int
    annotation: int  # index in scene_gt.json's list of the image
    object_id: int
    visible: float | None


class BopSet:
    """The instances of one kind (:data:`KINDS`) of a BOP dataset's split, read lazily.

    Parameters
    ----------
    root : str or Path
        The dataset folder.
    split : str
        Sub-folder of the split, e.g. ``"test"`` or ``"test_primesense"``.
    kind : str
        ``"crop"`` or ``"frame"``.
    scenes, objects : tuple of int, optional
        Only these scene and object ids (all when None).

    Raises
    ------
    FileNotFoundError
        Naming the missing folder or file (models, ``models_info.json``, a scene's
        ``scene_gt.json`` or ``scene_camera.json``).
    ValueError
        For a malformed file, an unknown kind, or a selection with no targets.
    """

    def __init__(self, root: str | Path, split: str = "test", kind: str = "crop", *,
                 scenes: tuple[int, ...] | None = None,
                 objects: tuple[int, ...] | None = None) -> None:
        if kind not in KINDS:
            raise ValueError(f"kind must be one of {KINDS}, got {kind!r}")
        self.root, self.split, self.kind = Path(root), split, kind
        if not self.root.is_dir():
            raise FileNotFoundError(f"no BOP dataset folder at {self.root}")
        self.spec = ("bop", str(self.root.resolve()), split, kind,
                     None if scenes is None else tuple(scenes),
                     None if objects is None else tuple(objects))
        self.name = f"{self.root.resolve().name}_{split}_{kind}"
        self.condition = f"bop_{kind}"
        self.surfaces_dir, self.points_dir = _models_dirs(self.root)
        self.models_info = read_json(self.surfaces_dir / "models_info.json", "the models' info")
        self._targets = _targets(self.root, split, scenes, objects)
        if not self._targets:
            raise ValueError(f"no annotated objects in {self.root / split} for scenes "
                             f"{scenes or 'all'} and objects {objects or 'all'}")
        self.manifest = {"seed": 0, "instances": [{"condition": self.condition}] * len(self)}

    def __len__(self) -> int:
        return len(self._targets)

    def __repr__(self) -> str:
        return (f"BopSet({str(self.root)!r}, split={self.split!r}, kind={self.kind!r}, "
                f"n={len(self)})")

    def model(self, object_id: int) -> _Model:
        """The model of ``object_id`` (read once per process)."""
        return _read_model(str(self.surfaces_dir), str(self.points_dir), object_id,
                           json.dumps(self.models_info.get(str(object_id))))

    def _scene_dir(self, target: _Target) -> Path:
        return self.root / self.split / f"{target.scene:06d}"

    def _camera(self, target: _Target) -> tuple[np.ndarray, np.ndarray]:
        """``K`` (3, 3) and the depth image (m) of a target's image."""
        scene = self._scene_dir(target)
        K, scale = _camera_entry(scene, str(target.image))
        raw = _read_png(scene / "depth" / f"{target.image:06d}.png").astype(np.float64)
        return K, raw * scale * _MM

    def _pose(self, target: _Target) -> np.ndarray:
        scene = self._scene_dir(target)
        entry = _scene_file(scene, "scene_gt.json")[str(target.image)][target.annotation]
        where = f"{scene / 'scene_gt.json'}, image {target.image}, annotation {target.annotation}"
        return entry_pose(entry, where)

    def __getitem__(self, index: int) -> Instance:
        """Instance ``index``: the model's points (m, with normals) as the source, the
        back-projected crop or frame (m, camera frame, normals to the camera) as the
        target, BOP's model-to-camera pose as ``T_gt`` and the model's symmetries;
        ``FileNotFoundError`` naming a missing depth image or mask."""
        target = self._targets[index]
        model = self.model(target.object_id)
        K, depth = self._camera(target)
        if self.kind == "crop":
            name = f"{target.image:06d}_{target.annotation:06d}.png"
            mask = _read_png(self._scene_dir(target) / "mask_visib" / name) > 0
            points = back_project(depth, K, mask)
        else:
            points = back_project(depth, K)
        cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
        if self.kind == "frame":
            cloud = cloud.voxel_down_sample(FRAME_VOXEL)
        if len(cloud.points) < 3:
            raise ValueError(f"{self._scene_dir(target)}: image {target.image}, object "
                             f"{target.object_id}: fewer than 3 depth pixels (empty target)")
        cloud.estimate_normals()
        cloud.orient_normals_towards_camera_location(np.zeros(3))
        source = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(model.points))
        source.normals = o3d.utility.Vector3dVector(model.normals)
        metadata = {"condition": self.condition, "object": f"obj_{target.object_id:06d}",
                    "scene": target.scene, "image": target.image,
                    "annotation": target.annotation, "visible_fraction": target.visible}
        return Instance(source, cloud, self._pose(target), np.zeros(len(cloud.points), int),
                        np.eye(4), metadata, known_symmetry=model.symmetry)

    def score(self, transformation: np.ndarray, index: int) -> dict:
        """BOP's errors of an estimate of instance ``index``: ``vsd`` (one per
        :data:`~o3d_spectral.harness.pose_metrics.VSD_TAUS`), ``mssd_m``, ``mspd_px``,
        with the object's ``diameter_m`` and the image's ``image_width_px``."""
        target = self._targets[index]
        model = self.model(target.object_id)
        K, depth = self._camera(target)
        T_gt, T = self._pose(target), np.asarray(transformation, dtype=np.float64)
        errors = pose_metrics.vsd(T, T_gt, model.mesh, depth, K, model.diameter)
        return {
            "vsd": [float(f"{e:.6g}") for e in errors],
            "mssd_m": pose_metrics.mssd(T, T_gt, model.points, model.symmetry),
            "mspd_px": pose_metrics.mspd(T, T_gt, model.points, K, model.symmetry),
            "diameter_m": model.diameter,
            "image_width_px": int(depth.shape[1]),
        }


def _models_dirs(root: Path) -> tuple[Path, Path]:
    """The folders of the models' surfaces (``models/``, else ``models_eval/``) and of
    their points (``models_eval/``, else ``models/``); ``FileNotFoundError`` if neither
    holds a ``models_info.json``."""
    found = [root / name for name in ("models", "models_eval")
             if (root / name / "models_info.json").is_file()]
    if not found:
        raise FileNotFoundError(f"no models/models_info.json or models_eval/models_info.json "
                                f"in {root}: is it a BOP dataset folder?")
    return found[0], found[-1]


@cache
def _scene_file(scene: Path, name: str) -> dict:
    document = read_json(scene / name, "a BOP scene's annotations")
    if not isinstance(document, dict):
        raise ValueError(f"{scene / name}: expected an object keyed by image id")
    return document


def _model_points(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Points (m) and normals of a model file: a mesh's vertices and vertex normals, or a
    cloud's points with its normals (estimated and oriented outward when it has none)."""
    with open(check_cloud_file(path), "rb") as handle:
        header = handle.read(4096).split(b"end_header")[0]
    mesh = o3d.io.read_triangle_mesh(str(path)) if b"element face" in header else None
    if mesh is not None and len(mesh.triangles) > 0:
        if not mesh.has_vertex_normals():
            mesh.compute_vertex_normals()
        points, normals = np.asarray(mesh.vertices), np.asarray(mesh.vertex_normals)
    else:
        cloud = o3d.io.read_point_cloud(str(path))
        if cloud.is_empty():
            raise ValueError(f"{path}: Open3D read no points from it")
        if not cloud.has_normals():
            cloud.estimate_normals()
            orient_outward(cloud)
        points, normals = np.asarray(cloud.points), np.asarray(cloud.normals)
    return _MM * points, normals.copy()


@cache
def _read_model(surfaces: str, points: str, object_id: int, info_text: str) -> _Model:
    """A model: its surface ``<surfaces>/obj_<id>.ply`` (mm), its points (and normals)
    from ``<points>/obj_<id>.ply``, and its ``models_info.json`` entry."""
    name = f"obj_{object_id:06d}.ply"
    where = f"{Path(surfaces) / 'models_info.json'}, object {object_id}"
    info = json.loads(info_text)
    if not isinstance(info, dict):
        raise ValueError(f"{where}: no entry (an object with the model's diameter)")
    diameter = number(info.get("diameter"), where, "diameter")
    if not diameter > 0:
        raise ValueError(f"{where}: diameter must be positive, got {diameter}")
    path = Path(surfaces) / name
    mesh = o3d.io.read_triangle_mesh(str(check_cloud_file(path)))
    if len(mesh.triangles) == 0:
        raise ValueError(f"{path}: no triangles (VSD renders the model's surface)")
    mesh.scale(_MM, center=np.zeros(3))
    vertices, normals = _model_points(Path(points) / name)
    return _Model(vertices, normals, mesh, _MM * diameter,
                  symmetry_of(info, where))


def _targets(root: Path, split: str, scenes, objects) -> list[_Target]:
    """The annotated objects of the split to evaluate, by scene, image and annotation."""
    folder = root / split
    if not folder.is_dir():
        raise FileNotFoundError(f"no split folder {folder} (choose --split)")
    listed = None
    targets_file = root / "test_targets_bop19.json"
    if split == "test" and targets_file.is_file():
        listed = listed_targets(read_json(targets_file, "BOP 19 test targets"), targets_file)
    chosen = []
    for scene_dir in sorted(p for p in folder.iterdir() if p.is_dir() and p.name.isdigit()):
        scene = int(scene_dir.name)
        if scenes is not None and scene not in scenes:
            continue
        truth = _scene_file(scene_dir, "scene_gt.json")
        info_path = scene_dir / "scene_gt_info.json"
        info = _scene_file(scene_dir, "scene_gt_info.json") if info_path.is_file() else None
        for image in sorted(truth, key=lambda key: image_id(key, scene_dir / "scene_gt.json")):
            _camera_entry(scene_dir, image)  # present and sound, or an error naming it
            entries = truth[image]
            if not isinstance(entries, list):
                raise ValueError(f"{scene_dir / 'scene_gt.json'}, image {image}: expected a "
                                 "list of annotations")
            for k, entry in enumerate(entries):
                where = f"{scene_dir / 'scene_gt.json'}, image {image}, annotation {k}"
                if not isinstance(entry, dict):
                    raise ValueError(f"{where}: expected an object (obj_id, cam_R_m2c, cam_t_m2c)")
                object_id = integer(entry.get("obj_id"), where, "obj_id")
                entry_pose(entry, where)
                visible = None if info is None else visible_fraction(info, image, k, info_path)
                if objects is not None and object_id not in objects:
                    continue
                if listed is not None and (scene, int(image), object_id) not in listed:
                    continue
                if visible is not None and visible < MIN_VISIBLE:
                    continue
                chosen.append(_Target(scene, int(image), k, object_id, visible))
    return chosen


def _camera_entry(scene: Path, image: str) -> tuple[np.ndarray, float]:
    """``K`` and the depth scale of ``image`` in ``scene_camera.json``, checked."""
    path = scene / "scene_camera.json"
    camera = _scene_file(scene, "scene_camera.json").get(image)
    where = f"{path}, image {image}"
    if not isinstance(camera, dict):
        raise ValueError(f"{where}: no entry for the image (cam_K, depth_scale)")
    K = array(camera.get("cam_K"), (3, 3), where, "cam_K")
    if abs(np.linalg.det(K)) < 1e-12:
        raise ValueError(f"{where}: cam_K is singular (not a camera matrix)")
    scale = number(camera.get("depth_scale", 1.0), where, "depth_scale")
    if not scale > 0:
        raise ValueError(f"{where}: depth_scale must be positive, got {scale}")
    return K, scale
