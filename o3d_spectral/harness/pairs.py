"""Scan pairs in the 3DMatch layout, as registration instances scored by registration recall.

A scene folder holds fragments ``cloud_bin_<k>.ply`` and the ground truth ``gt.log`` with
``gt.info`` (there or in the sibling folder ``<scene>-evaluation/``, as the 3DMatch
benchmark ships them). ``gt.log`` lists pairs as blocks of five lines::

    i  j  n            (fragment ids, fragments in the scene)
    4x4 transformation, one row a line

where the transformation takes fragment ``j`` onto fragment ``i``: the instance's source
is ``cloud_bin_<j>``, its target ``cloud_bin_<i>``. ``gt.info`` has the same header line
followed by a 6x6 information matrix (translation first) per pair.

Pairs are scored by both recalls that papers report:

* **RE / TE**: the rotation error under 15 degrees and the translation error (of the
  transformations, at the source frame's origin) under 30 cm, the criterion of the
  3DMatch results of FCGF, DGR and later work;
* **RMSE**: the benchmark's own (Choi et al. 2015, the Redwood and 3DMatch evaluation):
  the root mean square distance the error moves the pair's true correspondences,
  approximated to second order with ``gt.info`` (:func:`information_rmse`), under 20 cm.
  A scene without ``gt.info`` has no RMSE recall: its rows say so (``None``).

Fragments carry the normals of their file, else normals estimated by Open3D and turned to
the fragment frame's origin (the first camera of a 3DMatch fragment).
"""

from __future__ import annotations

from functools import cache
from pathlib import Path

import numpy as np
import open3d as o3d
from scipy.spatial.transform import Rotation

from o3d_spectral.harness.constants import (
    INFORMATION_TOLERANCE,
    MAX_RMSE_M,
    RECALL_ROTATION_DEG,
    RECALL_TRANSLATION_M,
)
from o3d_spectral.harness.errors import rotation_error, translation_error
from o3d_spectral.io.files import atomic_write_text, check_cloud_file, check_finite
from o3d_spectral.synthetic.instance import Instance
from o3d_spectral.synthetic.manifest import check_pose
from o3d_spectral.synthetic.symmetry import Symmetry

__all__ = ["MAX_RMSE_M", "RECALL_ROTATION_DEG", "RECALL_TRANSLATION_M", "PairSet",
           "information_matrix", "information_rmse", "pair_scenes", "read_log", "write_log"]


def information_rmse(transformation: np.ndarray, T_gt: np.ndarray,
                     information: np.ndarray) -> float:
    """The RMSE (m) by which ``transformation`` moves a pair's true correspondences away
    from each other, to second order, as the 3DMatch / Redwood benchmark scores it.

    With the error ``E = inv(T_gt) @ transformation``, its translation ``t`` and the
    vector part ``q`` of its unit quaternion (scalar part non-negative),
    ``xi = (t, q)`` and ``RMSE^2 = xi^T I xi / I[0, 0]``: ``I`` sums ``J^T J`` over the
    ``N`` correspondences ``p`` (in the source's frame) with ``J xi = t + 2 q x p``, so
    ``I[0, 0] = N``. For a turn about an axis through the origin with no slide,
    ``|2 q x p|`` is the chord that ``p`` travels: the RMSE is exact; otherwise it is
    exact to second order in the error.

    Parameters
    ----------
    transformation, T_gt : (4, 4) array
        The estimate and the ground truth, source onto target (m).
    information : (6, 6) array
        The pair's information matrix, translation first (``gt.info``).

    Returns
    -------
    float
        The RMSE in metres; the pair is recalled at most :data:`MAX_RMSE_M`.
    """
    error = np.linalg.inv(T_gt) @ transformation
    x, y, z, w = Rotation.from_matrix(error[:3, :3]).as_quat()
    xi = np.concatenate([error[:3, 3], np.copysign(1.0, w) * np.array([x, y, z])])
    return float(np.sqrt(max(0.0, xi @ information @ xi / information[0, 0])))


def information_matrix(source: o3d.geometry.PointCloud, target: o3d.geometry.PointCloud,
                       transformation: np.ndarray, distance: float = 0.002) -> np.ndarray:
    """The 6x6 information matrix of a pair in ``gt.info``'s convention
    (:func:`information_rmse`): summed over the source's points within ``distance`` (m)
    of the target once ``transformation`` places them, in the source's frame, translation
    first, rotation as the quaternion's vector part (Open3D's
    ``get_information_matrix_from_point_clouds`` reordered, its rotation-vector rows and
    columns doubled)."""
    matrix = o3d.pipelines.registration.get_information_matrix_from_point_clouds(
        target, source, distance, np.linalg.inv(transformation))
    order = [3, 4, 5, 0, 1, 2]  # Open3D's (rotation, translation) to translation first
    scale = np.array([1.0, 1.0, 1.0, 2.0, 2.0, 2.0])
    return np.asarray(matrix)[np.ix_(order, order)] * np.outer(scale, scale)


def _check_information(where: str, matrix: np.ndarray) -> None:
    """``ValueError`` naming ``where`` unless ``matrix`` is finite, symmetric positive
    semi-definite with a positive first entry (the correspondences' count)."""
    if not np.all(np.isfinite(matrix)):
        raise ValueError(f"{where}: information matrix has NaN or infinite values")
    scale = np.abs(matrix).max()
    asymmetry = np.abs(matrix - matrix.T).max()
    lowest = np.linalg.eigvalsh((matrix + matrix.T) / 2)[0] if scale > 0 else 0.0
    if asymmetry > INFORMATION_TOLERANCE * scale or lowest < -INFORMATION_TOLERANCE * scale:
        raise ValueError(f"{where}: information matrix is not symmetric positive "
                         f"semi-definite (asymmetry {asymmetry:.3g}, lowest eigenvalue "
                         f"{lowest:.3g}, largest entry {scale:.3g})")
    if not matrix[0, 0] > 0:
        raise ValueError(f"{where}: information matrix's first entry (the number of "
                         f"correspondences) is {matrix[0, 0]:.3g}, not positive")


def read_log(path: Path, size: int = 4) -> dict[tuple[int, int], np.ndarray]:
    """The pairs of a ``gt.log`` (``size`` 4) or ``gt.info`` (``size`` 6) file: by
    ``(i, j)``, the ``size`` x ``size`` matrix; ``ValueError`` naming the file and line of
    a malformed block."""
    if not path.is_file():
        raise FileNotFoundError(f"no {path.name} at {path}")
    _check_inside(path, path.parent)
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as error:
        raise ValueError(f"{path}: not a text file (byte {error.start} is not UTF-8)") from None
    lines = [line.split() for line in text.splitlines() if line.strip()]
    pairs = {}
    for start in range(0, len(lines), size + 1):
        block = lines[start:start + size + 1]
        try:
            i, j = int(block[0][0]), int(block[0][1])
            matrix = np.array([[float(v) for v in row] for row in block[1:]], dtype=np.float64)
            if matrix.shape != (size, size):
                raise ValueError(f"a {matrix.shape} matrix")
        except (IndexError, ValueError) as error:
            raise ValueError(f"{path}, line {start + 1}: not a pair block ({error})") from None
        where = f"{path}, pair {i} {j} (line {start + 1})"
        if size == 4:
            check_pose(where, "transformation", matrix)
        else:
            _check_information(where, matrix)
        pairs[(i, j)] = matrix
    if not pairs:
        raise ValueError(f"{path} lists no pairs")
    return pairs


def _check_inside(path: Path, folder: Path) -> None:
    """``ValueError`` when ``path`` is a link leading out of ``folder`` (its content, echoed
    in an error, would be another file's)."""
    if not path.resolve().is_relative_to(folder.resolve()):
        raise ValueError(f"{path} links out of its folder {folder}: copy the file there "
                         "instead of linking it")


def write_log(path: Path, pairs: dict[tuple[int, int], np.ndarray], fragments: int) -> None:
    """Write ``pairs`` (by ``(i, j)``, 4x4 or 6x6 matrices) as ``gt.log`` / ``gt.info``."""
    lines = []
    for (i, j), matrix in sorted(pairs.items()):
        lines.append(f"{i}\t{j}\t{fragments}")
        lines += ["\t".join(f"{v:.10e}" for v in row) for row in np.asarray(matrix)]
    atomic_write_text(path, "\n".join(lines) + "\n")


def _truth_dir(scene: Path) -> Path:
    for folder in (scene, scene.parent / f"{scene.name}-evaluation"):
        if (folder / "gt.log").is_file():
            return folder
    raise FileNotFoundError(f"no gt.log in {scene} nor in {scene.name}-evaluation/ beside it")


def pair_scenes(root: str | Path) -> list[Path]:
    """The scene folders of ``root``: itself when it holds ``cloud_bin_*.ply``, else its
    sub-folders that do (the 3DMatch test set's layout); ``FileNotFoundError`` if none."""
    root = Path(root)
    if not root.is_dir():
        raise FileNotFoundError(f"no pairs folder at {root}")
    if any(root.glob("cloud_bin_*.ply")):
        return [root]
    scenes = sorted(p for p in root.iterdir() if p.is_dir() and any(p.glob("cloud_bin_*.ply")))
    if not scenes:
        raise FileNotFoundError(f"no cloud_bin_*.ply in {root} nor in its sub-folders")
    return scenes


@cache
def _fragment(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Points (m) and normals of one fragment, read once per process."""
    _check_inside(path, path.parent)
    cloud = o3d.io.read_point_cloud(str(check_cloud_file(path)))
    if cloud.is_empty():
        raise ValueError(f"{path}: Open3D read no points from it")
    check_finite(np.asarray(cloud.points), path)
    if not cloud.has_normals():
        cloud.estimate_normals()
        cloud.orient_normals_towards_camera_location(np.zeros(3))
    return np.asarray(cloud.points).copy(), np.asarray(cloud.normals).copy()


class PairSet:
    """The pairs of one 3DMatch-layout scene folder, read lazily (see the module doc).

    Raises
    ------
    FileNotFoundError
        Naming the missing ``gt.log`` or fragment.
    ValueError
        For a malformed ``gt.log`` or ``gt.info`` (an information matrix that is not
        symmetric positive semi-definite included), or one listing other pairs.
    """

    def __init__(self, scene: str | Path) -> None:
        self.root = Path(scene)
        truth = _truth_dir(self.root)
        self.pairs = read_log(truth / "gt.log")
        #: The pairs' information matrices; ``None`` without ``gt.info`` (no RMSE recall).
        self.information = None
        if (truth / "gt.info").exists():
            self.information = read_log(truth / "gt.info", 6)
            if set(self.information) != set(self.pairs):
                raise ValueError(f"{truth / 'gt.info'} lists other pairs than "
                                 f"{truth / 'gt.log'}")
        self.keys = sorted(self.pairs)
        for i, j in self.keys:
            for k in (i, j):
                if (self.root / f"cloud_bin_{k}.ply").is_file():
                    _check_inside(self.root / f"cloud_bin_{k}.ply", self.root)
                else:
                    raise FileNotFoundError(f"{truth / 'gt.log'} lists fragment {k}, but "
                                            f"there is no {self.root / f'cloud_bin_{k}.ply'}")
        self.spec = ("pairs", str(self.root.resolve()))
        self.name = self.root.resolve().name
        self.condition = "pairs"
        self.manifest = {"seed": 0, "instances": [{"condition": "pairs"}] * len(self)}

    def __len__(self) -> int:
        return len(self.keys)

    def __repr__(self) -> str:
        return f"PairSet({str(self.root)!r}, n={len(self)})"

    def _cloud(self, k: int) -> o3d.geometry.PointCloud:
        points, normals = _fragment(self.root / f"cloud_bin_{k}.ply")
        cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
        cloud.normals = o3d.utility.Vector3dVector(normals)
        return cloud

    def __getitem__(self, index: int) -> Instance:
        """Pair ``index`` (in the order of ``(i, j)``): source ``cloud_bin_<j>``, target
        ``cloud_bin_<i>`` (m, with normals), ``T_gt`` from ``gt.log``, no symmetry."""
        i, j = self.keys[index]
        target = self._cloud(i)
        metadata = {"condition": "pairs", "object": self.name, "fragments": [j, i]}
        return Instance(self._cloud(j), target, self.pairs[(i, j)].copy(),
                        np.zeros(len(target.points), int), np.eye(4), metadata,
                        known_symmetry=Symmetry())

    def score(self, transformation: np.ndarray, index: int) -> dict:
        """Both recalls' errors of an estimate of pair ``index``: ``re_deg``, ``te_m`` (at
        the source frame's origin) and ``recalled`` (RE < 15 deg and TE < 30 cm);
        ``rmse_m`` (:func:`information_rmse`) and ``rmse_recalled`` (at most 20 cm), both
        ``None`` where the scene has no ``gt.info``."""
        T_gt = self.pairs[self.keys[index]]
        re = rotation_error(transformation, T_gt)
        te = translation_error(transformation, T_gt)
        rmse = None
        if self.information is not None:
            rmse = information_rmse(transformation, T_gt, self.information[self.keys[index]])
        return {"re_deg": re, "te_m": te,
                "recalled": bool(re < RECALL_ROTATION_DEG and te < RECALL_TRANSLATION_M),
                "rmse_m": rmse, "rmse_recalled": None if rmse is None else rmse <= MAX_RMSE_M}
