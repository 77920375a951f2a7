"""Benchmark: pose error of the global call against the clouds' distance from the origin.

The same registration problem is moved, whole, ``d`` metres from the origin of its frame
(0, 1, 10, 30, 50, 80, 99, 101 and 1000 m along a fixed oblique direction) and registered
by ``o3d_spectral.registration_spectral_global`` with the default polish and without it
(``refinement=None``). A registration should not depend on where the frame's origin is:
the errors should be the same at every distance.

Cases:

* ``mustard_model``: the bundled mustard bottle sampled twice (20k points each, different
  seeds, triangle normals), the second turned by 40 / -30 / 70 degrees (xyz) and moved
  by (3, -2, 5) cm; voxel 8 mm;
* ``dragon_0_24``: the dragon scans 0 and 24 degrees apart (``datasets/real``, no
  normals), the source turned by its first seeded random rotation; voxel 5 mm;
* ``ycbv_foam_brick``: the YCB-Video model of the foam brick into its crop (camera
  frame), the source turned by its second seeded random rotation; voxel 8 mm. The crop
  is a view from the camera, which is moved with it and given
  (``CloudOption(camera_location=..., target_viewpoint=...)``): away from the origin the
  origin is no longer the camera.

Errors: rotation (degrees) and translation at the source's centroid (mm), symmetry-aware
for the YCB-Video object (``o3d_spectral.harness.real.case_errors``), computed in the
case's own frame. Prints a markdown table (one row per distance, the spread over the
distances last) and writes it to ``--out`` when given, and its rows to ``--csv``.

Usage: python eval/bench_far.py [--out out/bench_far.md] [--csv out/bench_far.csv]
       [--cases mustard_model ...] [--distances 0 1000]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import open3d as o3d
from scipy.spatial.transform import Rotation

import o3d_spectral
from o3d_spectral.harness import real
from o3d_spectral.harness.writers import write_rows
from o3d_spectral.registration import DEFAULT_REFINEMENT
from o3d_spectral.synthetic import models

DISTANCES = (0.0, 1.0, 10.0, 30.0, 50.0, 80.0, 99.0, 101.0, 1000.0)
DIRECTION = np.array([0.6, -0.48, 0.64])  # unit, oblique to every axis
CASES = ("mustard_model", "dragon_0_24", "ycbv_foam_brick")


def _mustard() -> real.RealCase:
    mesh = models.load_model("mustard_bottle")
    clouds = []
    for seed in (0, 1):
        o3d.utility.random.seed(seed)
        clouds.append(mesh.sample_points_uniformly(20000, use_triangle_normal=True))
    motion = np.eye(4)
    motion[:3, :3] = Rotation.from_euler("xyz", [40, -30, 70], degrees=True).as_matrix()
    motion[:3, 3] = [0.03, -0.02, 0.05]
    target = clouds[1].transform(motion)
    return real.RealCase("mustard_model", "model", clouds[0], target, motion)


def _real(group: str, name: str, r: int) -> real.RealCase:
    case = next(c for c in real.load_cases([group]) if c.name == name)
    return real.randomly_rotated(case, real.rotation_seed(name, r))[0]


def cases() -> list[tuple[str, real.RealCase, np.ndarray, np.ndarray, float, bool]]:
    """(name, case for the errors, source array, target array, voxel, has a camera)."""
    out = []
    mustard, voxel = _mustard(), 0.008
    out.append(("mustard_model", mustard, np.hstack([np.asarray(mustard.source.points),
                                                      np.asarray(mustard.source.normals)]),
                np.hstack([np.asarray(mustard.target.points),
                           np.asarray(mustard.target.normals)]), voxel, False))
    dragon = _real("dragon_24", "dragon_0_24", 0)
    out.append(("dragon_0_24", dragon, np.asarray(dragon.source.points),
                np.asarray(dragon.target.points), 0.005, False))
    brick = _real("ycbv_crop", "ycbv_crop_061_foam_brick", 1)
    out.append(("ycbv_foam_brick", brick, np.asarray(brick.source.points),
                np.asarray(brick.target.points), 0.008, True))
    return out


def run(names: tuple[str, ...] = CASES, distances: tuple[float, ...] = DISTANCES
        ) -> dict[str, list[tuple[float, float, float, float, float]]]:
    """Per case of ``names`` (of :data:`CASES`), a row per distance of ``distances``
    (metres): (d, polished deg, polished mm, unpolished deg, mm)."""
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    table = {}
    for name, case, source, target, voxel, camera in cases():
        if name not in names:
            continue
        rows = []
        for d in distances:
            offset = DIRECTION * d
            shift = np.eye(4)
            shift[:3, 3] = offset
            moved = [np.hstack([a[:, :3] + offset, a[:, 3:]]) for a in (source, target)]
            cloud = (o3d_spectral.CloudOption(camera_location=tuple(offset),
                                              target_viewpoint=tuple(offset))
                     if camera else None)
            row = [d]
            for refinement in (DEFAULT_REFINEMENT, None):
                result = o3d_spectral.registration_spectral_global(
                    moved[0], moved[1], voxel, cloud=cloud, refinement=refinement)
                back = np.linalg.inv(shift) @ result.transformation @ shift
                degrees, metres = real.case_errors(back, case)
                row += [degrees, 1000.0 * metres]
            rows.append(tuple(row))
            print(name, " ".join(f"{x:.4f}" for x in row), flush=True)
        table[name] = rows
    return table


def markdown(table: dict) -> str:
    lines = []
    for name, rows in table.items():
        lines += [f"**{name}**", "",
                  "| distance (m) | polished: deg | polished: mm | law only: deg | law only: mm |",
                  "|" + " ---: |" * 5]
        lines += [f"| {d:g} | {a:.3f} | {b:.3f} | {c:.3f} | {e:.3f} |" for d, a, b, c, e in rows]
        spread = np.ptp(np.array(rows)[:, 1:], axis=0)
        lines += ["| spread | " + " | ".join(f"{x:.3f}" for x in spread) + " |", ""]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, help="write the markdown table here")
    parser.add_argument("--csv", type=Path, help="write one row per case and distance here")
    parser.add_argument("--cases", nargs="+", choices=CASES, default=list(CASES))
    parser.add_argument("--distances", type=float, nargs="+", default=list(DISTANCES),
                        help="metres from the origin")
    args = parser.parse_args()
    table = run(tuple(args.cases), tuple(args.distances))
    text = markdown(table)
    print(text)
    if args.csv:
        write_rows(args.csv, [
            {"case": name, "distance_m": d, "polished_deg": a, "polished_mm": b,
             "law_only_deg": c, "law_only_mm": e}
            for name, rows in table.items() for d, a, b, c, e in rows])
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text + "\n")


if __name__ == "__main__":
    main()
