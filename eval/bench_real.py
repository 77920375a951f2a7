"""Benchmark: the global spectral call against FPFH-RANSAC on the bundled real scans,
with the clouds' normals given three ways.

Cases (``o3d_spectral.harness.real``): the dragon scan pairs 24 / 48 / 72 degrees apart
and the YCB-Video models against their crop and the whole frame, each from
``--rotations`` seeded random rotations of the source (``real.rotation_seed``), at the
group's voxel size (``real.VOXEL_SIZES``). Normal modes (``real.with_normals``):
``oriented`` (towards each scan's sensor, models outward), ``unoriented`` (Open3D's
``estimate_normals()`` alone) and ``none``.

* spectral: ``o3d_spectral.registration_spectral_global(source, target, voxel)``, defaults;
* FPFH-RANSAC: the harness's ``fpfh_ransac`` (Open3D's tutorial), seeded per case; its
  point-to-plane ICP needs target normals: when the target has none the method estimates
  them (``harness.tutorial.with_target_normals``: 2 voxels, 30 neighbours) inside the timed
  call.

Success: rotation error < 5 deg and translation error at the source centroid < 1 cm
(``real.is_success``, symmetry-aware). Writes ``rows.csv`` (one row per case, rotation,
mode and method, with the estimate and the spectral call's ``confidence`` and warnings),
``summary.csv`` and ``summary.md`` (success and median time per group and mode) to
``--out``.

Usage: python eval/bench_real.py --out out/bench_real [--rotations 5] [--workers 2]
       [--groups dragon_24 ...] [--modes oriented unoriented none] [--limit 1]
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one thread per registration

import argparse  # noqa: E402
import time  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402
from multiprocessing import get_context  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from tqdm import tqdm  # noqa: E402

from o3d_spectral.harness import real  # noqa: E402
from o3d_spectral.harness.writers import write_rows  # noqa: E402

METHODS = ("spectral_global", "fpfh_ransac")


def _spectral(source, target, voxel: float, seed: int) -> tuple[np.ndarray, dict]:
    import o3d_spectral

    result = o3d_spectral.registration_spectral_global(source, target, voxel)
    return np.asarray(result.transformation), {
        "confidence": result.confidence, "warnings": " | ".join(result.warnings),
        "source_view": result.source_reading.view is not None,
        "target_viewpoint": result.target_viewpoint is not None,
    }


def _fpfh(source, target, voxel: float, seed: int) -> tuple[np.ndarray, dict]:
    from o3d_spectral.harness.methods import get_method

    transformation, _ = get_method("fpfh_ransac")(source, target, voxel, seed)
    return transformation, {}


def run(task: tuple[str, int, str]) -> list[dict]:
    """Both methods on one rotated case in one normal mode: a row each."""
    import open3d as o3d

    o3d.utility.set_max_threads(1)
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    name, r, mode = task
    group, case_name = name.split("/")
    seed = real.rotation_seed(case_name, r)
    original = next(c for c in real.load_cases([group]) if c.name == case_name)
    turned, motion = real.randomly_rotated(original, seed)
    case = real.with_normals(turned, mode, motion)
    voxel = real.VOXEL_SIZES[case.group]
    rows = []
    for method, call in zip(METHODS, (_spectral, _fpfh), strict=True):
        start = time.perf_counter()
        transformation, info = call(case.source, case.target, voxel, seed)
        seconds = time.perf_counter() - start
        rotation, translation = real.case_errors(transformation, case)
        rows.append({"group": case.group, "case": case.name, "rotation": r, "mode": mode,
                     "method": method, "seconds": seconds, "rotation_error_deg": rotation,
                     "translation_error_m": translation,
                     "success": real.is_success(rotation, translation),
                     "transformation": " ".join(f"{x:.9g}" for x in np.ravel(transformation))}
                    | info)
    return rows


def summarise(rows: list[dict]) -> list[dict]:
    """Success rate and median time per group, mode and method."""
    out = []
    keys = dict.fromkeys((r["group"], r["mode"]) for r in rows)
    for group, mode in keys:
        line = {"group": group, "mode": mode}
        for method in METHODS:
            key = (group, mode, method)
            mine = [r for r in rows if (r["group"], r["mode"], r["method"]) == key]
            line["n"] = len(mine)
            line[f"{method}_success"] = float(np.mean([r["success"] for r in mine]))
            line[f"{method}_median_s"] = float(np.median([r["seconds"] for r in mine]))
        out.append(line)
    return out


def markdown(summary: list[dict]) -> str:
    lines = ["| group | normals | n | spectral success | FPFH-RANSAC success "
             "| spectral median s | FPFH median s |", "|" + " --- |" * 7]
    for s in summary:
        lines.append(
            f"| {s['group']} | {s['mode']} | {s['n']} "
            f"| {100 * s['spectral_global_success']:.0f}% | {100 * s['fpfh_ransac_success']:.0f}% "
            f"| {s['spectral_global_median_s']:.2f} | {s['fpfh_ransac_median_s']:.2f} |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("out/bench_real"))
    parser.add_argument("--rotations", type=int, default=5, help="random rotations per case")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--groups", nargs="+", choices=real.GROUPS, default=list(real.GROUPS))
    parser.add_argument("--modes", nargs="+", choices=real.NORMAL_MODES,
                        default=list(real.NORMAL_MODES))
    parser.add_argument("--limit", type=int, help="only the first N cases of each group")
    args = parser.parse_args()
    groups = [g for g in real.GROUPS if g in args.groups]  # load_cases's order
    cases = [case for group in groups for case in real.load_cases([group])[:args.limit]]
    tasks = [(f"{case.group}/{case.name}", r, mode) for case in cases
             for r in range(args.rotations) for mode in args.modes]
    rows: list[dict] = []
    with ProcessPoolExecutor(args.workers, mp_context=get_context("spawn")) as pool:
        for done in tqdm(pool.map(run, tasks), total=len(tasks), desc="bench_real", unit="run"):
            rows += done
    summary = summarise(rows)
    args.out.mkdir(parents=True, exist_ok=True)
    write_rows(args.out / "rows.csv", rows)
    write_rows(args.out / "summary.csv", summary)
    table = markdown(summary)
    (args.out / "summary.md").write_text(table + "\n")
    print(table)


if __name__ == "__main__":
    main()
