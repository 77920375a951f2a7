"""A folder of "original" real data, in the layout ``eval/derive_real_data.py`` and
``o3d-spectral convert ycbv`` read, rebuilt from the bundled data.

The bundled files are derived from the originals (``o3d_spectral/datasets/real``: the
scans and crops as float32, the frame down-sampled; ``o3d_spectral/datasets/bop_ycbv``:
the frame's every pixel, depth to 0.1 mm), so the originals are rebuilt from them: the
dragon scans, crops, poses and intrinsics copied, the model clouds written as text, and
the whole frame back-projected from the BOP depth image (one point per pixel).
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import open3d as o3d

from o3d_spectral.harness.real import DRAGON_ANGLES, YCBV_CLASSES, real_dir

PACKAGE = Path(__file__).resolve().parents[1] / "o3d_spectral"
#: The bundled YCB-Video frame in the BOP layout.
BOP_YCBV = PACKAGE / "datasets" / "bop_ycbv"
FRAME = "0000_000001"
#: YCB-Video's classes in the order of their object ids (BOP's ids 1 to 21).
YCBV_IDS = (
    "002_master_chef_can", "003_cracker_box", "004_sugar_box", "005_tomato_soup_can",
    "006_mustard_bottle", "007_tuna_fish_can", "008_pudding_box", "009_gelatin_box",
    "010_potted_meat_can", "011_banana", "019_pitcher_base", "021_bleach_cleanser",
    "024_bowl", "025_mug", "035_power_drill", "036_wood_block", "037_scissors",
    "040_large_marker", "051_large_clamp", "052_extra_large_clamp", "061_foam_brick",
)


def frame_points() -> np.ndarray:
    """Every pixel of the bundled BOP depth image back-projected (N, 3; metres, camera
    frame): pixel ``(u, v)`` at depth ``z`` is ``z K^-1 (u, v, 1)``."""
    K = np.loadtxt(real_dir() / "ycbv" / FRAME / "K.txt").reshape(3, 3)
    raw = np.asarray(o3d.io.read_image(str(BOP_YCBV / "test/000000/depth/000001.png")))
    v, u = np.nonzero(raw)
    z = raw[v, u] * 0.1e-3  # depth_scale 0.1: tenths of a millimetre
    pixels = np.column_stack([u, v, np.ones_like(u)]).astype(float)
    return z[:, None] * (pixels @ np.linalg.inv(K).T)


def write_originals(root: Path) -> Path:
    """Write the originals' folder ``root`` (``dragon/``, ``ycbv/``) and return it."""
    real = real_dir()
    dragon = root / "dragon"
    dragon.mkdir(parents=True)
    names = [f"dragonStandRight_{a}.ply" for a in DRAGON_ANGLES]
    for name in [*names, "dragonStandRight.conf", "README.stanford"]:
        shutil.copyfile(real / "dragon" / name, dragon / name)
    ycbv, frame = root / "ycbv", root / "ycbv" / FRAME
    frame.mkdir(parents=True)
    shutil.copyfile(real / "ycbv" / "LICENSE", ycbv / "LICENSE")
    (ycbv / "classes.txt").write_text("\n".join(YCBV_IDS) + "\n")
    shutil.copyfile(real / "ycbv" / FRAME / "K.txt", frame / "K.txt")
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(frame_points()))
    o3d.io.write_point_cloud(str(frame / "scene.ply"), cloud)
    for name in YCBV_CLASSES:
        for file in (f"{name}_crop.ply", f"{name}_T_cam_from_model.txt"):
            shutil.copyfile(real / "ycbv" / FRAME / file, frame / file)
        model = np.asarray(o3d.io.read_point_cloud(str(real / "ycbv" / "models" /
                                                       f"{name}.ply")).points)
        (ycbv / "models" / name).mkdir(parents=True)
        np.savetxt(ycbv / "models" / name / "points.xyz", model, fmt="%.9g")
    return root
