"""The poses of one object of an ``eval --bop`` run scored by BOP's metrics, and the
true pose turned about the object's axis scored the same way.

For each method's row of the object (crop and whole frame): the symmetry-aware rotation
and translation errors of the harness, VSD at three of its ``tau`` (0.05, 0.25, 0.5 of
the diameter), the VSD, MSSD and MSPD recalls of that one pose, and whether the harness
counts it a success. Then the ground truth turned by a few angles about the model's axis
of (near) rotational symmetry (the principal axis about which a quarter turn fits the
model cloud best, refined by ``o3d_spectral.synthetic.symmetry.refine_axis``), with its
VSD and MSSD: what a metric says of poses that differ by a turn about the axis.

Usage: python eval/bop_poses.py RUN [--dataset o3d_spectral/datasets/bop_ycbv]
[--object 14]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import open3d as o3d
from scipy.spatial import cKDTree

from o3d_spectral.harness import pose_metrics as pm
from o3d_spectral.harness.bop import BopSet
from o3d_spectral.harness.records import load_results
from o3d_spectral.spectra import so3
from o3d_spectral.synthetic.symmetry import refine_axis

TURNS_DEG = (0, 5, 10, 20, 45, 90, 180)
TAUS = (0, 4, 9)  # indices of tau 0.05, 0.25, 0.5


def _recalls(score: dict) -> str:
    vsd = pm.vsd_recall(np.array([score["vsd"]]))
    mssd = pm.mssd_recall([score["mssd_m"]], [score["diameter_m"]])
    mspd = pm.mspd_recall([score["mspd_px"]], [score["image_width_px"]])
    return f"{vsd:.2f} | {mssd:.2f} | {mspd:.2f}"


def method_rows(run: Path, object_name: str) -> None:
    frame = load_results(run)
    rows = frame[(frame["object"] == object_name) & frame["condition"].str.startswith("bop_")]
    print("| instances | method | rotation (deg) | translation (mm) | VSD at tau 0.05 / 0.25 / "
          "0.5 | recall VSD | MSSD | MSPD | success |")
    print("| --- | --- | ---: | ---: | --- | ---: | ---: | ---: | --- |")
    for _, row in rows.iterrows():
        vsd = " / ".join(f"{row['vsd'][k]:.2f}" for k in TAUS)
        print(f"| {row['suite']} | {row['method']} | {row['rotation_error_sym_deg']:.1f} | "
              f"{1e3 * row['translation_error_sym_m']:.1f} | {vsd} | {_recalls(row)} | "
              f"{'yes' if row['success'] else 'no'} |")


def turned_truths(dataset: Path, object_id: int) -> None:
    crops = BopSet(dataset, objects=(object_id,))
    model, truth = crops.model(object_id), crops[0].T_gt
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(model.points))
    cloud.normals = o3d.utility.Vector3dVector(model.normals)
    centre = model.points.mean(axis=0)
    principal = np.linalg.eigh(np.cov((model.points - centre).T))[1]
    tree, best = cKDTree(model.points), None
    for i in range(3):
        axis, point = refine_axis(cloud, principal[:, i], np.pi / 2, centre)
        turned = (model.points - point) @ so3.exp(axis * np.pi / 2).T + point
        residual = float(np.median(tree.query(turned)[0]))
        if best is None or residual < best[0]:
            best = (residual, axis, point)
    residual, axis, point = best
    print(f"\naxis {np.round(axis, 3).tolist()} (model frame), a quarter turn about it "
          f"leaves the points a median {1e3 * residual:.1f} mm from the cloud\n")
    print("| turn (deg) | VSD at tau 0.05 / 0.25 / 0.5 | MSSD (mm) | recall VSD | MSSD | MSPD |")
    print("| ---: | --- | ---: | ---: | ---: | ---: |")
    for degrees in TURNS_DEG:
        motion = so3.about_pivot(so3.exp(axis * np.deg2rad(degrees)), np.zeros(3), point)
        score = crops.score(truth @ motion, 0)
        vsd = " / ".join(f"{score['vsd'][k]:.2f}" for k in TAUS)
        print(f"| {degrees} | {vsd} | {1e3 * score['mssd_m']:.1f} | {_recalls(score)} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path)
    parser.add_argument("--dataset", type=Path, default=Path("o3d_spectral/datasets/bop_ycbv"))
    parser.add_argument("--object", type=int, default=14, help="object id (14: the mug)")
    args = parser.parse_args()
    method_rows(args.run, f"obj_{args.object:06d}")
    turned_truths(args.dataset, args.object)


if __name__ == "__main__":
    main()
