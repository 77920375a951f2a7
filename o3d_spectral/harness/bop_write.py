"""Writing a small dataset in the BOP layout (read by :mod:`o3d_spectral.harness.bop`):
models with ``models_info.json``, and depth images with their annotations.

Lengths are given in metres and written in BOP's millimetres; depth PNGs are 16-bit with
a ``depth_scale`` (millimetres per unit) of 0.1 by default, so depth up to 6.5 m is kept to
0.1 mm. Used by ``o3d-spectral convert`` (:mod:`o3d_spectral.harness.converters`) and by
the tests' built datasets.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import open3d as o3d

from o3d_spectral.synthetic.symmetry import Symmetry

__all__ = ["diameter", "write_image", "write_model"]

_MM = 1e3  # millimetres per metre


def _update_json(path: Path, key: str, value) -> None:
    """Set ``key`` of the JSON object in ``path`` (created if missing)."""
    document = json.loads(path.read_text()) if path.is_file() else {}
    document[key] = value
    path.parent.mkdir(parents=True, exist_ok=True)
    ordered = dict(sorted(document.items(), key=lambda item: int(item[0])))
    path.write_text(json.dumps(ordered, indent=1) + "\n")


def _write_ply(path: Path, points: np.ndarray, normals: np.ndarray,
               triangles: np.ndarray | None = None) -> None:
    """A binary PLY of single-precision points and normals, and triangles if given."""
    vertex = np.empty(len(points), dtype=[(k, "<f4") for k in ("x", "y", "z", "nx", "ny", "nz")])
    for k, column in zip(vertex.dtype.names, np.hstack([points, normals]).T, strict=True):
        vertex[k] = column
    header = ["ply", "format binary_little_endian 1.0", f"element vertex {len(points)}"]
    header += [f"property float {k}" for k in vertex.dtype.names]
    faces = b""
    if triangles is not None:
        face = np.empty(len(triangles), dtype=[("n", "u1"), ("v", "<i4", (3,))])
        face["n"], face["v"] = 3, triangles
        header += [f"element face {len(triangles)}", "property list uchar int vertex_indices"]
        faces = face.tobytes()
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(("\n".join([*header, "end_header"]) + "\n").encode() + vertex.tobytes()
                     + faces)


def diameter(points: np.ndarray) -> float:
    """The largest distance (m) between two of ``points`` (N, 3): over the vertices of
    their convex hull."""
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.asarray(points, float)))
    hull = np.asarray(cloud.compute_convex_hull()[0].vertices)
    gaps = np.linalg.norm(hull[:, None] - hull[None], axis=2)
    return float(gaps.max())


def _symmetry_entries(symmetry: Symmetry) -> dict:
    """``models_info.json``'s symmetry entries (mm) of a group."""
    entries: dict = {}
    if len(symmetry.discrete) > 1:
        scaled = symmetry.discrete[1:].copy()
        scaled[:, :3, 3] *= _MM
        entries["symmetries_discrete"] = [m.ravel().tolist() for m in scaled]
    if symmetry.axis is not None:
        entries["symmetries_continuous"] = [
            {"axis": symmetry.axis.tolist(), "offset": (_MM * symmetry.center).tolist()}
        ]
    return entries


def write_model(root: Path, object_id: int, mesh: o3d.geometry.TriangleMesh,
                symmetry: Symmetry | None = None,
                points: o3d.geometry.PointCloud | None = None) -> Path:
    """Write ``models/obj_<id>.ply`` (millimetres, with vertex normals) and its entry of
    ``models/models_info.json`` (diameter, bounding box, symmetries); with ``points``,
    also ``models_eval/obj_<id>.ply`` (the points, with their normals) and the same
    entry in ``models_eval/models_info.json``.

    Parameters
    ----------
    root : Path
        The dataset folder.
    object_id : int
    mesh : open3d.geometry.TriangleMesh
        The model's surface in its own frame (m), which VSD renders.
    symmetry : Symmetry, optional
        Its symmetry group in that frame (none when omitted).
    points : open3d.geometry.PointCloud, optional
        The model's points (m) with normals, for the registrations, MSSD and MSPD; the
        mesh's vertices when omitted.
    """
    scaled = o3d.geometry.TriangleMesh(mesh)
    scaled.scale(_MM, center=np.zeros(3))
    if not scaled.has_vertex_normals():
        scaled.compute_vertex_normals()
    name = f"obj_{object_id:06d}.ply"
    _write_ply(Path(root) / "models" / name, np.asarray(scaled.vertices),
               np.asarray(scaled.vertex_normals), np.asarray(scaled.triangles))
    folders = ["models"]
    vertices = np.asarray(mesh.vertices)
    if points is not None:
        vertices = np.asarray(points.points)
        _write_ply(Path(root) / "models_eval" / name, vertices * _MM,
                   np.asarray(points.normals))
        folders.append("models_eval")
    low, size = vertices.min(axis=0) * _MM, np.ptp(vertices, axis=0) * _MM
    info = {"diameter": diameter(vertices) * _MM}
    info |= {f"min_{a}": float(v) for a, v in zip("xyz", low, strict=True)}
    info |= {f"size_{a}": float(v) for a, v in zip("xyz", size, strict=True)}
    info |= _symmetry_entries(symmetry or Symmetry())
    for folder in folders:
        _update_json(Path(root) / folder / "models_info.json", str(object_id), info)
    return Path(root) / "models" / name


def write_image(
    scene_dir: Path,
    image_id: int,
    depth: np.ndarray,
    K: np.ndarray,
    annotations: Sequence[tuple[int, np.ndarray, np.ndarray, float | None]],
    *,
    depth_scale: float = 0.1,
) -> None:
    """Write one image of a scene: ``depth/<image>.png``, ``mask_visib/<image>_<k>.png``
    and its entries of ``scene_gt.json``, ``scene_camera.json`` and ``scene_gt_info.json``.

    Parameters
    ----------
    scene_dir : Path
        ``<dataset>/<split>/<scene:06d>``.
    image_id : int
    depth : ndarray, shape (H, W)
        Depth (z) in metres, 0 where there is none.
    K : ndarray, shape (3, 3)
        Intrinsics (pixels).
    annotations : sequence of (object_id, T, mask, visible_fraction)
        Per object: its model-to-camera pose ``T`` (4, 4; metres), the boolean mask
        (H, W) of its visible pixels and the visible share of its image (None if not
        known).
    depth_scale : float, optional
        Millimetres per unit of the depth PNG.
    """
    scene_dir = Path(scene_dir)
    for sub in ("depth", "mask_visib"):
        (scene_dir / sub).mkdir(parents=True, exist_ok=True)
    units = np.round(np.asarray(depth, dtype=np.float64) * _MM / depth_scale)
    if units.max() > np.iinfo(np.uint16).max:
        raise ValueError(f"depth over {np.iinfo(np.uint16).max * depth_scale / _MM:.2f} m "
                         f"does not fit a 16-bit PNG at depth_scale {depth_scale}")
    o3d.io.write_image(str(scene_dir / "depth" / f"{image_id:06d}.png"),
                       o3d.geometry.Image(units.astype(np.uint16)))
    truth, info = [], []
    for k, (object_id, T, mask, visible) in enumerate(annotations):
        image = (np.asarray(mask, dtype=bool) * 255).astype(np.uint8)
        o3d.io.write_image(str(scene_dir / "mask_visib" / f"{image_id:06d}_{k:06d}.png"),
                           o3d.geometry.Image(image))
        T = np.asarray(T, dtype=np.float64)
        truth.append({"cam_R_m2c": T[:3, :3].ravel().tolist(),
                      "cam_t_m2c": (T[:3, 3] * _MM).tolist(), "obj_id": int(object_id)})
        entry = {"px_count_visib": int(np.count_nonzero(mask))}
        if visible is not None:
            entry["visib_fract"] = float(visible)
        info.append(entry)
    camera = {"cam_K": np.asarray(K, dtype=np.float64).ravel().tolist(),
              "depth_scale": depth_scale}
    _update_json(scene_dir / "scene_gt.json", str(image_id), truth)
    _update_json(scene_dir / "scene_camera.json", str(image_id), camera)
    _update_json(scene_dir / "scene_gt_info.json", str(image_id), info)
