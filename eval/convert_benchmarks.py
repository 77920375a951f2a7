"""Write the real data as benchmark folders: the YCB-Video frame in the BOP layout, the
dragon scans in the 3DMatch layout.

``ycbv SOURCE``: reads the original YCB-Video frame (laid out as for
``eval/derive_real_data.py``: ``SOURCE/ycbv/0000_000001/{scene.ply, K.txt,
<class>_crop.ply, <class>_T_cam_from_model.txt}``, ``SOURCE/ycbv/models/<class>/points.xyz``,
``SOURCE/ycbv/classes.txt``) and writes a BOP folder (default
``o3d_spectral/datasets/bop_ycbv``):

* ``test/000000/depth/000001.png``: every pixel of ``scene.ply`` (each point is one pixel,
  back-projected at integer pixel coordinates; depth kept to 0.1 mm, ``depth_scale`` 0.1);
* ``mask_visib/000001_<k>.png``: the pixels of the object's crop (the label mask's);
* ``scene_gt.json``: the poses ``<class>_T_cam_from_model.txt`` (rotation made exactly
  orthonormal, as :mod:`o3d_spectral.harness.real` does);
* ``models_eval/obj_<id>.ply``: the model cloud (2,621 points) with its normals
  (estimated, oriented outward by :func:`o3d_spectral.harness.real.orient_outward`), what
  the registrations, MSSD and MSPD use; object ids are the classes' lines in
  ``classes.txt`` (BOP's YCB-V ids);
* ``models/obj_<id>.ply``: a surface of it for VSD: Open3D's screened Poisson
  reconstruction (octree depth 7) without its vertices farther than 1 cm from every
  point (the surface it invents where there are none: across the mug's opening and
  its handle's hole). Its distances to the
  points are printed (and recorded in the folder's README). Open3D's Poisson
  reconstruction does not repeat to the bit (two runs here differ by up to 2 mm in
  vertex positions, one thread or several; one run in several ended in a crash inside
  Open3D: run it again): the surfaces in the package are one run's;
* ``models_info.json``: diameters and the symmetries the harness finds for the bundled
  models (:func:`o3d_spectral.harness.real.ycbv_symmetry`).

``dragon OUT``: writes the bundled dragon scans as a 3DMatch scene folder
(:func:`o3d_spectral.harness.real.write_dragon_pairs`).

Usage::

    python eval/convert_benchmarks.py ycbv SOURCE
    python eval/convert_benchmarks.py dragon out/dragon_3dmatch
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

import numpy as np
import open3d as o3d
from scipy.spatial import cKDTree

from o3d_spectral.harness import bop_write, pose_metrics
from o3d_spectral.harness.real import (
    YCBV_CLASSES,
    orient_outward,
    write_dragon_pairs,
    ycbv_symmetry,
)
from o3d_spectral.spectra import so3

FRAME = "0000_000001"
SHAPE = (480, 640)
POISSON_DEPTH, POISSON_TRIM = 7, 0.01  # octree depth; metres


def _pixels(points: np.ndarray, K: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows and columns of camera-frame points back-projected from integer pixels."""
    image = points @ K.T
    uv = image[:, :2] / image[:, 2:3]
    rounded = np.round(uv)
    if np.max(np.abs(uv - rounded)) > 1e-6:
        raise ValueError("points are not back-projected from integer pixel coordinates")
    return rounded[:, 1].astype(int), rounded[:, 0].astype(int)


def surface(points: np.ndarray) -> tuple[o3d.geometry.TriangleMesh, o3d.geometry.PointCloud, dict]:
    """Screened Poisson surface of a model cloud (less its vertices farther than
    ``POISSON_TRIM`` from every point), the cloud with its normals, and the distances
    between the surface and the points (mm)."""
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    cloud.estimate_normals()
    orient_outward(cloud)
    mesh, density = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(
        cloud, depth=POISSON_DEPTH)
    far = cKDTree(points).query(np.asarray(mesh.vertices))[0] > POISSON_TRIM
    mesh.remove_vertices_by_mask(far)
    mesh.compute_vertex_normals()
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(mesh))
    to_surface = scene.compute_distance(o3d.core.Tensor(points.astype(np.float32))).numpy()
    o3d.utility.random.seed(0)
    samples = np.asarray(mesh.sample_points_uniformly(20000).points)
    to_points = cKDTree(points).query(samples)[0]
    stats = {"triangles": len(mesh.triangles)}
    for label, gaps in (("points_to_surface", to_surface), ("surface_to_points", to_points)):
        for q, name in ((0.5, "median"), (0.95, "p95"), (1.0, "max")):
            stats[f"{label}_{name}_mm"] = 1e3 * float(np.quantile(gaps, q))
    return mesh, cloud, stats


def convert_ycbv(source: Path, out: Path) -> None:
    frame = source / "ycbv" / FRAME
    K = np.loadtxt(frame / "K.txt").reshape(3, 3)
    scene = np.asarray(o3d.io.read_point_cloud(str(frame / "scene.ply")).points)
    depth = np.zeros(SHAPE)
    rows, cols = _pixels(scene, K)
    depth[rows, cols] = scene[:, 2]
    classes = (source / "ycbv" / "classes.txt").read_text().split()
    for folder in ("models", "models_eval", "test"):  # the README stays
        shutil.rmtree(out / folder, ignore_errors=True)
    annotations = []
    for name in YCBV_CLASSES:
        object_id = classes.index(name) + 1
        points = np.loadtxt(source / "ycbv" / "models" / name / "points.xyz")
        mesh, cloud, stats = surface(points)
        print(name, f"obj_{object_id:06d}", ", ".join(f"{k} {v:.3g}" for k, v in stats.items()))
        bop_write.write_model(out, object_id, mesh, ycbv_symmetry(name), cloud)
        T = np.loadtxt(frame / f"{name}_T_cam_from_model.txt").reshape(4, 4)
        T[:3, :3] = so3.project_to_rotation(T[:3, :3])
        crop = np.asarray(o3d.io.read_point_cloud(str(frame / f"{name}_crop.ply")).points)
        mask = np.zeros(SHAPE, dtype=bool)
        mask[_pixels(crop, K)] = True
        whole = np.count_nonzero(pose_metrics.render_depth(mesh, T, K, SHAPE))
        visible = min(1.0, np.count_nonzero(mask) / max(whole, 1))
        annotations.append((object_id, T, mask, visible))
        print(f"  {np.count_nonzero(mask)} visible pixels, {whole} rendered: {visible:.2f}")
    bop_write.write_image(out / "test" / "000000", 1, depth, K, annotations)
    shutil.copyfile(source / "ycbv" / "LICENSE", out / "LICENSE")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("which", choices=("ycbv", "dragon"))
    parser.add_argument("path", type=Path, help="ycbv: the originals' folder; dragon: OUT")
    parser.add_argument("--out", type=Path, default=Path("o3d_spectral/datasets/bop_ycbv"))
    args = parser.parse_args()
    if args.which == "ycbv":
        convert_ycbv(args.path, args.out)
    else:
        print(write_dragon_pairs(args.path))


if __name__ == "__main__":
    main()
