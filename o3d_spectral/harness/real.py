"""Registration cases on real sensor data (``o3d_spectral/datasets/real``; see its
``README.md``).

Two sets, each with a verified ground truth:

* the Stanford dragon (Cyberware laser scans on a turntable, 24 degrees apart): scan to
  scan, in groups ``"dragon_24"`` to ``"dragon_120"`` (every pair of scans that far
  apart, source the earlier scan; 96 and 120 degrees apart most pairs share 5-18% of
  their surface);
* one YCB-Video RGB-D frame (Asus Xtion): the YCB-Video model points of three objects
  against the object's crop by the label mask (``"ycbv_crop"``) or against the whole
  frame (``"ycbv_frame"``, down-sampled to 2 mm), both in the camera frame.

Clouds are legacy ``open3d.geometry.PointCloud`` in metres, float64, **without normals**
(as a user gets them from a scanner). ``T_gt`` maps source onto target
(``target ~ T_gt @ source``). :func:`randomly_rotated` turns a case's source by a seeded
rotation uniform over SO(3) and returns the matching ground truth.

The folder is the package data ``o3d_spectral/datasets/real``, read through
:mod:`importlib.resources`; the environment variable ``O3D_SPECTRAL_REAL_DATA`` names
another.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable, Iterator
from functools import cache
from pathlib import Path
from typing import NamedTuple

import numpy as np
import open3d as o3d
from scipy.spatial.transform import Rotation

from o3d_spectral.common.bundled import bundled_folder
from o3d_spectral.harness.constants import (
    DRAGON_ANGLES,
    DRAGON_SENSOR,
    DRAGON_VOXEL,
    MAX_ROTATION_DEG,
    MAX_TRANSLATION_M,
)
from o3d_spectral.harness.errors import symmetric_rotation_error, symmetric_translation_error
from o3d_spectral.io.files import atomic_write_cloud
from o3d_spectral.spectra import so3
from o3d_spectral.synthetic.symmetry import Symmetry, surface_symmetry

__all__ = [
    "DRAGON_ANGLES",
    "DRAGON_VOXEL",
    "GROUPS",
    "NORMAL_MODES",
    "YCBV_CLASSES",
    "RealCase",
    "dragon_cases",
    "dragon_pose",
    "load_cases",
    "randomly_rotated",
    "real_dir",
    "with_normals",
    "VOXEL_SIZES",
    "rotated_cases",
    "rotation_seed",
    "case_errors",
    "is_success",
    "case_score",
    "orient_outward",
    "ycbv_symmetry",
    "write_dragon_pairs",
]

#: The YCB-Video classes in the bundled frame.
YCBV_CLASSES: tuple[str, ...] = ("009_gelatin_box", "025_mug", "061_foam_brick")
#: The groups of cases, in order.
GROUPS: tuple[str, ...] = ("dragon_24", "dragon_48", "dragon_72", "dragon_96", "dragon_120",
                           "ycbv_crop", "ycbv_frame")
#: How :func:`with_normals` gives a case's clouds normals: as a sensor's software would
#: ("oriented"), as Open3D's ``estimate_normals()`` alone leaves them ("unoriented"), or
#: none (the method estimates its own).
NORMAL_MODES: tuple[str, ...] = ("oriented", "unoriented", "none")
#: Voxel size (metres) each group is registered at: the YCB-Video objects are the suites'.
VOXEL_SIZES: dict[str, float] = {**{g: DRAGON_VOXEL for g in GROUPS if g.startswith("dragon")},
                                 "ycbv_crop": 0.008, "ycbv_frame": 0.008}
_FRAME = "0000_000001"
_MARKER = Path("dragon") / "dragonStandRight.conf"


class RealCase(NamedTuple):
    """One registration problem on real data.

    Attributes
    ----------
    name : str
        E.g. ``"dragon_0_24"`` (source scan, target scan) or ``"ycbv_crop_025_mug"``.
    group : str
        One of :data:`GROUPS`.
    source, target : open3d.geometry.PointCloud
        Metres, no normals; new copies on every load.
    T_gt : ndarray, shape (4, 4), float64
        Ground truth, ``target ~ T_gt @ source``.
    symmetry : Symmetry
        The source object's symmetry group in the source's frame (:func:`ycbv_symmetry`;
        trivial for the dragon).
    """

    name: str
    group: str
    source: o3d.geometry.PointCloud
    target: o3d.geometry.PointCloud
    T_gt: np.ndarray
    symmetry: Symmetry = Symmetry()


def real_dir() -> Path:
    """Folder holding the bundled real data (``dragon/``, ``ycbv/``).

    Raises
    ------
    FileNotFoundError
        If no candidate folder holds ``dragon/dragonStandRight.conf``.
    """
    return bundled_folder("real", "O3D_SPECTRAL_REAL_DATA",
                          lambda folder: (folder / _MARKER).is_file(), "real data")


@cache
def _points(relative: str) -> np.ndarray:
    """The points of a bundled PLY (float64, metres), read once per process (read-only)."""
    path = real_dir() / relative
    cloud = o3d.io.read_point_cloud(str(path))
    if cloud.is_empty():
        raise ValueError(f"no points read from {path}")
    points = np.asarray(cloud.points, dtype=np.float64).copy()
    points.flags.writeable = False
    return points


def _cloud(relative: str) -> o3d.geometry.PointCloud:
    return o3d.geometry.PointCloud(o3d.utility.Vector3dVector(_points(relative).copy()))


def dragon_pose(angle: int) -> np.ndarray:
    """The pose ``W`` (4x4) of the dragon scan at ``angle`` degrees: ``p_world = W p``.

    From the line ``bmesh dragonStandRight_<angle>.ply tx ty tz qi qj qk qr`` of
    ``dragonStandRight.conf``: ``W = [R^T | t]`` with ``R`` the quaternion's matrix
    (the conjugate: ``R p + t`` is wrong and leaves about 2% overlap).
    """
    wanted = f"dragonStandRight_{angle}.ply"
    for line in (real_dir() / _MARKER).read_text().splitlines():
        fields = line.split()
        if len(fields) == 9 and fields[0] == "bmesh" and fields[1] == wanted:
            t, q = np.array(fields[2:5], dtype=float), np.array(fields[5:9], dtype=float)
            pose = np.eye(4)
            pose[:3, :3] = Rotation.from_quat(q).as_matrix().T
            pose[:3, 3] = t
            return pose
    raise ValueError(f"no dragon scan at {angle} degrees; bundled: {DRAGON_ANGLES}")


def dragon_cases(step: int) -> list[RealCase]:
    """Every pair of bundled dragon scans ``step`` degrees apart (a multiple of 24, up to
    168; :func:`load_cases` groups 24-120), the first scan the source, its group
    ``f"dragon_{step}"``."""
    cases = []
    for a in DRAGON_ANGLES:
        b = a + step
        if b not in DRAGON_ANGLES:
            continue
        T_gt = np.linalg.inv(dragon_pose(b)) @ dragon_pose(a)  # A -> B = inv(W_B) W_A
        cases.append(RealCase(
            f"dragon_{a}_{b}", f"dragon_{step}", _cloud(f"dragon/dragonStandRight_{a}.ply"),
            _cloud(f"dragon/dragonStandRight_{b}.ply"), T_gt,
        ))
    return cases


def write_dragon_pairs(out: str | Path, max_step: int = 72) -> Path:
    """Write the dragon scans as a 3DMatch-layout scene folder (:mod:`~o3d_spectral.
    harness.pairs`): ``cloud_bin_<k>.ply`` the scan at ``24 k`` degrees with normals
    (Open3D's estimate turned to the scanner, :data:`DRAGON_SENSOR`), ``gt.log`` every
    pair at most ``max_step`` degrees apart (72: the pairs sharing 55% or more of their
    surface; 3DMatch lists those sharing over 30%) with the transformation taking scan
    ``j`` onto scan ``i``, ``inv(W_i) W_j`` (:func:`dragon_pose`), and ``gt.info`` the
    pairs' information matrices in the benchmark's convention (:func:`~o3d_spectral.
    harness.pairs.information_matrix`).

    Returns
    -------
    Path
        The folder ``out`` (created if missing).
    """
    from o3d_spectral.harness.pairs import information_matrix, write_log

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    clouds = []
    for k, angle in enumerate(DRAGON_ANGLES):
        cloud = _cloud(f"dragon/dragonStandRight_{angle}.ply")
        cloud.estimate_normals()
        cloud.orient_normals_towards_camera_location(np.asarray(DRAGON_SENSOR))
        atomic_write_cloud(out / f"cloud_bin_{k}.ply", len(cloud.points),
                           lambda name, cloud=cloud: o3d.io.write_point_cloud(name, cloud))
        clouds.append(cloud)
    log, info = {}, {}
    for i, a in enumerate(DRAGON_ANGLES):
        for j, b in enumerate(DRAGON_ANGLES):
            if 0 < b - a <= max_step:
                log[(i, j)] = np.linalg.inv(dragon_pose(a)) @ dragon_pose(b)
                info[(i, j)] = information_matrix(clouds[j], clouds[i], log[(i, j)])
    write_log(out / "gt.log", log, len(DRAGON_ANGLES))
    write_log(out / "gt.info", info, len(DRAGON_ANGLES))
    return out


def _ycbv_cases(group: str) -> list[RealCase]:
    cases = []
    for name in YCBV_CLASSES:
        target = f"ycbv/{_FRAME}/" + (
            f"{name}_crop.ply" if group == "ycbv_crop" else "scene_2mm.ply"
        )
        T_gt = np.loadtxt(real_dir() / "ycbv" / _FRAME / f"{name}_T_cam_from_model.txt")
        T_gt = T_gt.reshape(4, 4)  # its rotation is orthonormal to 1e-6 only: made exact
        T_gt[:3, :3] = so3.project_to_rotation(T_gt[:3, :3])
        cases.append(RealCase(
            f"{group}_{name}", group, _cloud(f"ycbv/models/{name}.ply"), _cloud(target),
            T_gt, ycbv_symmetry(name),
        ))
    return cases


def load_cases(groups: tuple[str, ...] | list[str] | None = None) -> list[RealCase]:
    """The real registration cases of ``groups`` (all of :data:`GROUPS` when None), in the
    order of :data:`GROUPS`: 7, 6, 5, 4 and 3 dragon pairs, 3 crops, 3 whole-frame cases.

    Raises
    ------
    ValueError
        If a group is unknown.
    """
    chosen = GROUPS if groups is None else tuple(groups)
    unknown = [g for g in chosen if g not in GROUPS]
    if unknown:
        raise ValueError(f"unknown groups {unknown}; choose from {', '.join(GROUPS)}")
    cases: list[RealCase] = []
    for group in GROUPS:
        if group in chosen:
            cases += (
                dragon_cases(int(group.split("_")[1])) if group.startswith("dragon")
                else _ycbv_cases(group)
            )
    return cases


def randomly_rotated(case: RealCase, seed: int) -> tuple[RealCase, np.ndarray]:
    """The case with its source turned about its centroid by a random rotation.

    The rotation is uniform over SO(3) (Haar), drawn from ``numpy.random.default_rng(seed)``;
    the same seed gives the same cloud. The target is unchanged (a new copy).

    Returns
    -------
    case : RealCase
        Same name and group; ``source`` moved by ``M``; ``T_gt`` becomes ``T_gt @ inv(M)``.
    M : ndarray, shape (4, 4), float64
        The motion applied to the source: ``x -> R (x - c) + c``, ``c`` its centroid.
    """
    rng = np.random.default_rng(seed)
    rotation = Rotation.random(random_state=rng).as_matrix()
    points = np.asarray(case.source.points)
    centre = points.mean(axis=0)
    M = np.eye(4)
    M[:3, :3], M[:3, 3] = rotation, centre - rotation @ centre
    source = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points @ rotation.T + M[:3, 3]))
    target = o3d.geometry.PointCloud(case.target)
    return case._replace(source=source, target=target, T_gt=case.T_gt @ np.linalg.inv(M),
                         symmetry=case.symmetry.transformed(M)), M


def with_normals(case: RealCase, mode: str, motion: np.ndarray | None = None) -> RealCase:
    """The case with normals on both clouds as :data:`NORMAL_MODES` ``mode`` says.

    Normals are estimated by Open3D's ``estimate_normals()`` (its default: PCA over 30
    neighbours) on new copies. ``"oriented"`` then turns them towards each cloud's sensor:
    the dragon scanner (:data:`DRAGON_SENSOR` in the scan's frame) and the YCB-Video
    camera (the camera frame's origin), or, for a YCB-Video model, consistently along
    the surface and outward (Open3D's ``orient_normals_consistent_tangent_plane(10)``,
    the sign making the mean of ``n . (p - centroid)`` positive). ``"unoriented"`` leaves
    the signs as the estimate gives them; ``"none"`` returns copies without normals.

    Parameters
    ----------
    case : RealCase
    mode : str
        One of :data:`NORMAL_MODES`.
    motion : ndarray, shape (4, 4), optional
        The motion :func:`randomly_rotated` applied to the source, which turns its
        sensor with it.
    """
    if mode not in NORMAL_MODES:
        raise ValueError(f"unknown normal mode {mode!r}; choose from {', '.join(NORMAL_MODES)}")
    motion = np.eye(4) if motion is None else np.asarray(motion, dtype=np.float64)
    source, target = o3d.geometry.PointCloud(case.source), o3d.geometry.PointCloud(case.target)
    if mode == "none":
        return case._replace(source=source, target=target)
    for cloud in (source, target):
        cloud.estimate_normals()
    if mode == "oriented":
        dragon = case.group.startswith("dragon")
        sensor = np.asarray(DRAGON_SENSOR) if dragon else np.zeros(3)
        target.orient_normals_towards_camera_location(sensor)
        if dragon:
            source.orient_normals_towards_camera_location(motion[:3, :3] @ sensor + motion[:3, 3])
        else:
            orient_outward(source)
    return case._replace(source=source, target=target)


def orient_outward(model: o3d.geometry.PointCloud) -> None:
    """A model's normals oriented consistently along its surface, then outward."""
    model.orient_normals_consistent_tangent_plane(10)
    points, normals = np.asarray(model.points), np.asarray(model.normals)
    if np.mean(np.einsum("ij,ij->i", normals, points - points.mean(axis=0))) < 0.0:
        model.normals = o3d.utility.Vector3dVector(-normals)


def rotated_cases(
    groups: tuple[str, ...] | list[str] | None, rotations: int
) -> Iterator[tuple[RealCase, np.ndarray, int, int]]:
    """Every case of ``groups`` from ``rotations`` seeded random rotations of its source.

    Yields ``(case, M, seed, r)``: the case turned by :func:`randomly_rotated` with the
    seed :func:`rotation_seed`, its motion ``M``,
    the seed and ``r`` in ``range(rotations)``.
    """
    for case in load_cases(groups):
        for r in range(rotations):
            seed = rotation_seed(case.name, r)
            turned, motion = randomly_rotated(case, seed)
            yield turned, motion, seed, r


def rotation_seed(name: str, r: int) -> int:
    """The seed of a case's ``r``-th random rotation: ``crc32("<name>/<r>")`` (31 bits),
    the same across runs and machines."""
    return zlib.crc32(f"{name}/{r}".encode()) & 0x7FFFFFFF


def case_errors(transformation: np.ndarray, case: RealCase) -> tuple[float, float]:
    """Symmetry-aware rotation error (degrees) and translation error at the source's
    centroid (metres) of an estimate ``transformation`` (4, 4) against ``case.T_gt``:
    the smallest over the object's symmetry group (a box turned half a turn about one of
    its axes fits its view as well as the truth)."""
    centre = np.asarray(case.source.points).mean(axis=0)
    return (symmetric_rotation_error(transformation, case.T_gt, case.symmetry),
            symmetric_translation_error(transformation, case.T_gt, case.symmetry,
                                        center=centre))


@cache
def ycbv_symmetry(class_name: str) -> Symmetry:
    """Symmetry group of a bundled YCB-Video model cloud, in its own frame.

    The kinds recorded for the same YCB object's mesh
    (:func:`o3d_spectral.synthetic.symmetry.surface_symmetry`), found on the model's points
    (normals estimated, oriented outward; axes from the points' second moments).

    Parameters
    ----------
    class_name : str
        One of :data:`YCBV_CLASSES`, e.g. ``"061_foam_brick"``.
    """
    cloud = _cloud(f"ycbv/models/{class_name}.ply")
    cloud.estimate_normals()
    orient_outward(cloud)
    points = np.asarray(cloud.points)
    centre = points.mean(axis=0)
    principal = np.linalg.eigh(np.cov((points - centre).T))[1]
    return surface_symmetry(cloud, class_name.split("_", 1)[1], centre, principal)


def is_success(rotation_deg: float, translation_m: float) -> bool:
    """Both errors under :data:`MAX_ROTATION_DEG` and :data:`MAX_TRANSLATION_M`."""
    return bool(rotation_deg < MAX_ROTATION_DEG and translation_m < MAX_TRANSLATION_M)


def case_score(case: RealCase) -> Callable[[np.ndarray], tuple[float, float, bool]]:
    """``(T) -> (rotation error deg, translation error m, success)`` of an estimate ``T``
    (4, 4) of ``case``: :func:`case_errors` and :func:`is_success`."""

    def score(transformation: np.ndarray) -> tuple[float, float, bool]:
        rotation, translation = case_errors(transformation, case)
        return rotation, translation, is_success(rotation, translation)

    return score
