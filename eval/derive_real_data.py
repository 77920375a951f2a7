"""Derive the bundled real data (``o3d_spectral/datasets/real/``) from the original
files.

Not run at run time: the package reads only ``o3d_spectral/datasets/real/``. Re-run this to
rebuild it from a copy of the originals (Stanford dragon scans, one YCB-Video frame), laid out as::

    SOURCE/dragon/dragonStandRight_{0,24,...,168}.ply, dragonStandRight.conf, README.stanford
    SOURCE/ycbv/LICENSE, ycbv/models/<class>/points.xyz
    SOURCE/ycbv/0000_000001/{scene.ply, K.txt, <class>_crop.ply, <class>_T_cam_from_model.txt}

What it changes: positions become float32 (binary little-endian PLY, ``x y z`` only); the
YCB-Video scene is down-sampled with Open3D's ``voxel_down_sample(0.002)`` (the centroid of
the points in each 2 mm voxel); the model clouds (``points.xyz``, text) become PLY. The
dragon scans and object crops keep every point. Text files are copied unchanged.

Usage: python eval/derive_real_data.py SOURCE [--out o3d_spectral/datasets/real]
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

import numpy as np
import open3d as o3d

SCENE_VOXEL = 0.002
DRAGON_ANGLES = range(0, 169, 24)
CLASSES = ("009_gelatin_box", "025_mug", "061_foam_brick")
FRAME = "0000_000001"


def write_ply(path: Path, points: np.ndarray) -> None:
    """Binary little-endian PLY with float32 ``x y z``."""
    points = np.ascontiguousarray(points, dtype="<f4")
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"comment derived by o3d-spectral eval/derive_real_data.py\n"
        f"element vertex {len(points)}\n"
        "property float x\nproperty float y\nproperty float z\nend_header\n"
    )
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "wb") as handle:
        handle.write(header.encode("ascii"))
        handle.write(points.tobytes())


def read_points(path: Path) -> np.ndarray:
    cloud = o3d.io.read_point_cloud(str(path))
    if cloud.is_empty():
        raise ValueError(f"no points read from {path}")
    return np.asarray(cloud.points)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("source", type=Path)
    parser.add_argument("--out", type=Path, default=Path("o3d_spectral/datasets/real"))
    args = parser.parse_args()
    src, out = args.source, args.out

    for angle in DRAGON_ANGLES:
        name = f"dragonStandRight_{angle}.ply"
        write_ply(out / "dragon" / name, read_points(src / "dragon" / name))
    for name in ("dragonStandRight.conf", "README.stanford"):
        shutil.copyfile(src / "dragon" / name, out / "dragon" / name)

    frame_in, frame_out = src / "ycbv" / FRAME, out / "ycbv" / FRAME
    scene = o3d.io.read_point_cloud(str(frame_in / "scene.ply"))
    down = scene.voxel_down_sample(SCENE_VOXEL)
    write_ply(frame_out / "scene_2mm.ply", np.asarray(down.points))
    print(f"scene: {len(scene.points)} -> {len(down.points)} points at 2 mm")
    shutil.copyfile(frame_in / "K.txt", frame_out / "K.txt")
    for name in CLASSES:
        write_ply(frame_out / f"{name}_crop.ply", read_points(frame_in / f"{name}_crop.ply"))
        truth = f"{name}_T_cam_from_model.txt"
        shutil.copyfile(frame_in / truth, frame_out / truth)
        model = np.loadtxt(src / "ycbv" / "models" / name / "points.xyz")
        write_ply(out / "ycbv" / "models" / f"{name}.ply", model)
    shutil.copyfile(src / "ycbv" / "LICENSE", out / "ycbv" / "LICENSE")


if __name__ == "__main__":
    main()
