"""The real data written as benchmark folders: the YCB-Video frame in the BOP layout
(:mod:`~o3d_spectral.harness.bop`), the dragon scans in the 3DMatch layout
(:mod:`~o3d_spectral.harness.pairs`). ``o3d-spectral convert`` runs them.

:func:`convert_ycbv` reads the original YCB-Video frame, laid out as::

    SOURCE/ycbv/classes.txt              the YCB-V class names, one a line (line k: id k)
    SOURCE/ycbv/LICENSE
    SOURCE/ycbv/models/<class>/points.xyz            the model cloud (text, metres)
    SOURCE/ycbv/0000_000001/scene.ply                the frame, one point per pixel
    SOURCE/ycbv/0000_000001/K.txt                    the intrinsics (3 x 3, pixels)
    SOURCE/ycbv/0000_000001/<class>_crop.ply         the object's pixels (label mask)
    SOURCE/ycbv/0000_000001/<class>_T_cam_from_model.txt    its pose (4 x 4, metres)

for each class of :data:`~o3d_spectral.harness.real.YCBV_CLASSES`, and writes a BOP
folder:

* ``test/000000/depth/000001.png``: every pixel of ``scene.ply`` (each point is one pixel,
  back-projected at integer pixel coordinates; depth kept to 0.1 mm, ``depth_scale`` 0.1);
* ``mask_visib/000001_<k>.png``: the pixels of the object's crop (the label mask's);
* ``scene_gt.json``: the poses ``<class>_T_cam_from_model.txt`` (rotation made exactly
  orthonormal, as :mod:`o3d_spectral.harness.real` does);
* ``models_eval/obj_<id>.ply``: the model cloud with its normals (estimated, oriented
  outward by :func:`~o3d_spectral.harness.real.orient_outward`), what the registrations,
  MSSD and MSPD use; object ids are the classes' lines in ``classes.txt`` (BOP's YCB-V
  ids);
* ``models/obj_<id>.ply``: a surface of it for VSD (:func:`model_surface`);
* ``models_info.json``: diameters and the symmetries the harness finds for the bundled
  models (:func:`~o3d_spectral.harness.real.ycbv_symmetry`).

Open3D's Poisson reconstruction does not repeat to the bit (two runs differ by up to 2 mm
in vertex positions, one thread or several; one run in several ended in a crash inside
Open3D: run it again): the surfaces in the package are one run's.

The dragon scans are written by :func:`o3d_spectral.harness.real.write_dragon_pairs`.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import open3d as o3d
from scipy.spatial import cKDTree

from .constants import IMAGE_SHAPE, PIXEL_TOLERANCE, POISSON_DEPTH, POISSON_TRIM

__all__ = ["FRAME", "IMAGE_SHAPE", "PIXEL_TOLERANCE", "POISSON_DEPTH", "POISSON_TRIM",
           "convert_ycbv", "model_surface", "ycbv_originals"]

#: The YCB-Video frame's folder in the originals.
FRAME = "0000_000001"
#: What :func:`convert_ycbv` writes in its folder; anything else there stops it.
_WRITTEN = frozenset({"README.md", "LICENSE", "models", "models_eval", "test"})


def ycbv_originals(source: str | Path) -> list[Path]:
    """The files :func:`convert_ycbv` reads from ``source``, in the layout of the module's
    docstring.

    Raises
    ------
    FileNotFoundError
        If ``source`` is not a folder, or one of the files is missing (the message names
        the first missing one).
    """
    from o3d_spectral.harness.real import YCBV_CLASSES

    source = Path(source)
    if not source.is_dir():
        raise FileNotFoundError(f"SOURCE {source}: no such folder")
    ycbv, frame = source / "ycbv", source / "ycbv" / FRAME
    files = [ycbv / "classes.txt", ycbv / "LICENSE", frame / "scene.ply", frame / "K.txt"]
    for name in YCBV_CLASSES:
        files += [ycbv / "models" / name / "points.xyz", frame / f"{name}_crop.ply",
                  frame / f"{name}_T_cam_from_model.txt"]
    for path in files:
        if not path.is_file():
            raise FileNotFoundError(
                f"SOURCE {source} has no {path.relative_to(source)} (the originals' layout: "
                "ycbv/classes.txt, ycbv/LICENSE, ycbv/models/<class>/points.xyz, "
                f"ycbv/{FRAME}/{{scene.ply, K.txt, <class>_crop.ply, "
                "<class>_T_cam_from_model.txt}})")
    return files


def _points(path: Path) -> np.ndarray:
    """The points (N, 3) of a point cloud file; an error naming it when it has none."""
    points = np.asarray(o3d.io.read_point_cloud(str(path)).points)
    if len(points) == 0:
        raise ValueError(f"{path}: Open3D read no points from it")
    return points


def _pixels(points: np.ndarray, K: np.ndarray, path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Rows and columns (N,) of camera-frame points (N, 3; metres) back-projected from
    integer pixels of an :data:`IMAGE_SHAPE` image; an error naming ``path`` otherwise."""
    image = points @ K.T
    uv = image[:, :2] / image[:, 2:3]
    rounded = np.round(uv)
    off = float(np.max(np.abs(uv - rounded)))
    if off > PIXEL_TOLERANCE:
        raise ValueError(f"{path}: the points are not back-projected from integer pixel "
                         f"coordinates (one is {off:.3g} px off)")
    rows, cols = rounded[:, 1].astype(int), rounded[:, 0].astype(int)
    if rows.min() < 0 or cols.min() < 0 or rows.max() >= IMAGE_SHAPE[0] \
            or cols.max() >= IMAGE_SHAPE[1]:
        raise ValueError(f"{path}: points fall outside the {IMAGE_SHAPE[1]} x "
                         f"{IMAGE_SHAPE[0]} image")
    return rows, cols


def model_surface(
    points: np.ndarray,
) -> tuple[o3d.geometry.TriangleMesh, o3d.geometry.PointCloud, dict[str, float]]:
    """A model cloud's surface for VSD: Open3D's screened Poisson reconstruction (octree
    depth :data:`POISSON_DEPTH`) without its vertices farther than :data:`POISSON_TRIM`
    from every point (the surface it invents where there are none: across a mug's opening
    and its handle's hole).

    Parameters
    ----------
    points : ndarray, shape (N, 3)
        The model's points, metres.

    Returns
    -------
    mesh : open3d.geometry.TriangleMesh
        The surface (metres), with vertex normals.
    cloud : open3d.geometry.PointCloud
        The points with normals (estimated, oriented outward).
    stats : dict of str to float
        ``triangles`` and the distances (mm) between the surface and the points:
        ``points_to_surface_{median,p95,max}_mm`` (each point to the surface) and
        ``surface_to_points_{median,p95,max}_mm`` (20,000 points sampled uniformly on
        the surface, seeded, to the nearest point).
    """
    from o3d_spectral.harness.real import orient_outward

    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    cloud.estimate_normals()
    orient_outward(cloud)
    mesh, _ = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(
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
    stats: dict[str, float] = {"triangles": float(len(mesh.triangles))}
    for label, gaps in (("points_to_surface", to_surface), ("surface_to_points", to_points)):
        for q, name in ((0.5, "median"), (0.95, "p95"), (1.0, "max")):
            stats[f"{label}_{name}_mm"] = 1e3 * float(np.quantile(gaps, q))
    return mesh, cloud, stats


def convert_ycbv(source: str | Path, out: str | Path) -> list[dict]:
    """Write the original YCB-Video frame in ``source`` as a BOP folder ``out``.

    Parameters
    ----------
    source : str or Path
        The originals, laid out as the module's docstring says (:func:`ycbv_originals`).
    out : str or Path
        The BOP folder, created if missing. Its ``models``, ``models_eval`` and ``test``
        folders are replaced and its ``LICENSE`` written; a ``README.md`` stays.

    Returns
    -------
    list of dict
        Per object, in the order of :data:`~o3d_spectral.harness.real.YCBV_CLASSES`:
        ``class``, ``object_id``, the surface's ``stats`` (:func:`model_surface`),
        ``visible_pixels`` (its mask's), ``rendered_pixels`` (the surface rendered at the
        pose alone) and ``visible_fraction`` (their ratio, at most 1).

    Raises
    ------
    FileNotFoundError
        If a file of the originals is missing (named).
    ValueError
        If ``out`` holds anything but what this writes, a class is not in
        ``classes.txt``, or a cloud is not one point per pixel (the file named).
    """
    from o3d_spectral.harness import bop_write, pose_metrics
    from o3d_spectral.harness.real import YCBV_CLASSES, ycbv_symmetry
    from o3d_spectral.spectra import so3

    source, out = Path(source), Path(out)
    ycbv_originals(source)
    if out.exists() and not out.is_dir():
        raise ValueError(f"OUT {out} is a file, not a folder")
    if out.is_dir():
        other = sorted(p.name for p in out.iterdir() if p.name not in _WRITTEN)
        if other:
            raise ValueError(f"OUT {out} holds {other[0]}, which is not part of a BOP folder "
                             f"this writes ({', '.join(sorted(_WRITTEN))}): choose another OUT")
    frame = source / "ycbv" / FRAME
    K = np.loadtxt(frame / "K.txt").reshape(3, 3)
    scene = _points(frame / "scene.ply")
    depth = np.zeros(IMAGE_SHAPE)
    rows, cols = _pixels(scene, K, frame / "scene.ply")
    depth[rows, cols] = scene[:, 2]
    classes_file = source / "ycbv" / "classes.txt"
    classes = classes_file.read_text().split()
    missing = [name for name in YCBV_CLASSES if name not in classes]
    if missing:
        raise ValueError(f"{classes_file} does not list {', '.join(missing)}")
    for folder in ("models", "models_eval", "test"):
        shutil.rmtree(out / folder, ignore_errors=True)
    annotations, written = [], []
    for name in YCBV_CLASSES:
        object_id = classes.index(name) + 1
        points = np.loadtxt(source / "ycbv" / "models" / name / "points.xyz")
        mesh, cloud, stats = model_surface(points)
        bop_write.write_model(out, object_id, mesh, ycbv_symmetry(name), cloud)
        T = np.loadtxt(frame / f"{name}_T_cam_from_model.txt").reshape(4, 4)
        T[:3, :3] = so3.project_to_rotation(T[:3, :3])
        crop_file = frame / f"{name}_crop.ply"
        mask = np.zeros(IMAGE_SHAPE, dtype=bool)
        mask[_pixels(_points(crop_file), K, crop_file)] = True
        whole = int(np.count_nonzero(pose_metrics.render_depth(mesh, T, K, IMAGE_SHAPE)))
        visible = int(np.count_nonzero(mask))
        fraction = min(1.0, visible / max(whole, 1))
        annotations.append((object_id, T, mask, fraction))
        written.append({"class": name, "object_id": object_id, "stats": stats,
                        "visible_pixels": visible, "rendered_pixels": whole,
                        "visible_fraction": fraction})
    bop_write.write_image(out / "test" / "000000", 1, depth, K, annotations)
    shutil.copyfile(source / "ycbv" / "LICENSE", out / "LICENSE")
    return written
