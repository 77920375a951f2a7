"""Benchmark: wall time of ``o3d-spectral report`` on the full benchmark's number of rows.

Writes a synthetic run folder (``fake_run``: 4 suites x 240 instances x 12 methods, the
columns ``eval`` writes, convergence curves of 10-120 iterations for the spectral
methods, one session) and times ``make_report`` on it, with a profile of the slowest
calls when ``--profile`` is given. The rows are random, not results.

Usage: python eval/bench_report.py [--out out/bench_report] [--instances 240] [--profile]
"""

from __future__ import annotations

import argparse
import cProfile
import json
import pstats
import time
from pathlib import Path

import numpy as np

CONDITIONS = ("full", "partial", "occluded", "cluttered")
METHODS = (
    "spectral",
    "spectral_paper",
    "spectral_global",
    "spectral_global_unrefined",
    "spectral_global_whole_egi",
    "icp_point_to_point",
    "icp_point_to_plane",
    "fpfh_ransac",
    "fgr",
    "fpfh_ransac_tuned",
    "kiss_matcher",
    "small_gicp",
)
OBJECTS = ("mug", "mustard_bottle", "bowl", "banana", "scissors", "power_drill")


def _row(rng: np.random.Generator, condition: str, index: int, method: str) -> dict:
    rotation = float(rng.lognormal(-1.0, 2.0))
    translation = float(rng.lognormal(-6.5, 1.5))
    success = rotation <= 5.0 and translation <= 0.01
    row = {
        "suite": condition,
        "index": index,
        "method": method,
        "condition": condition,
        "object": OBJECTS[index % len(OBJECTS)],
        "init_angle_deg": float(rng.uniform(0, 180)),
        "init_offset_m": float(rng.uniform(0, 0.1)),
        "visible_fraction": None if condition == "full" else float(rng.uniform(0.2, 0.6)),
        "occlusion": float(rng.uniform(0.2, 0.7)) if condition == "occluded" else None,
        "seed": int(rng.integers(2**31)),
        "time_s": float(rng.lognormal(-1.5, 1.0)),
        "error": None,
        "rotation_error_deg": rotation,
        "translation_error_m": translation,
        "rotation_error_sym_deg": rotation,
        "translation_error_sym_m": translation,
        "success": success,
        "squared_translation_error_m2": translation**2,
        "squared_rotation_error_rad2": np.deg2rad(rotation) ** 2,
        "indistinguishable": None if success else bool(rng.random() < 0.3),
        "fitness": float(rng.random()),
        "inlier_rmse": float(rng.random() * 0.004),
        "iterations": None,
        "converged": None,
        "translation_gradient_norm_m": None,
        "rotation_gradient_norm_rad": None,
        "transformation": np.eye(4).tolist(),
    }
    if method.startswith("spectral"):
        k = int(rng.integers(10, 120))
        decay = np.exp(-np.arange(k) / 10.0)
        row |= {"iterations": k, "converged": True}
        row |= {"translation_gradient_norm_m": 1e-5, "rotation_gradient_norm_rad": 1e-5}
        row["curve_rotation_deg"] = [float(f"{v:.6g}") for v in 90 * decay + rotation]
        row["curve_translation_m"] = [float(f"{v:.6g}") for v in 0.05 * decay + translation]
    return row


def fake_run(out: Path, instances: int = 240, seed: int = 0) -> Path:
    """Write a synthetic run folder (old single-file layout) and return it."""
    rng = np.random.default_rng(seed)
    out.mkdir(parents=True, exist_ok=True)
    with (out / "results.jsonl").open("w") as sink:
        for condition in CONDITIONS:
            for index in range(instances):
                for method in METHODS:
                    sink.write(json.dumps(_row(rng, condition, index, method)) + "\n")
    machine = {"cpu": "fake", "cores": 2, "memory_gib": 8.0, "platform": "fake"}
    session = {"started": "2026-01-01T00:00:00", "seconds": 3540.0, "workers": 2}
    session |= {"registrations": 4 * instances * len(METHODS), "complete": True}
    session |= {"machine": machine, "commit": None, "versions": {"python": "3"}}
    config = {"voxel_size": 0.008, "seed": 0}
    config |= {"criteria": {"max_rotation_deg": 5.0, "max_translation_m": 0.01}}
    config |= {"suites": [], "methods": list(METHODS), "sessions": [session]}
    (out / "config.json").write_text(json.dumps(config))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("out/bench_report"))
    parser.add_argument("--instances", type=int, default=240, help="per suite (default 240)")
    parser.add_argument("--profile", action="store_true", help="print the slowest calls")
    args = parser.parse_args()
    run = fake_run(args.out / "fake_run", args.instances)
    # Not timed: importing the package. Timed: pandas and matplotlib, which make_report
    # imports on first use, as the command does.
    from o3d_spectral.harness.report import make_report

    profiler = cProfile.Profile() if args.profile else None
    start, cpu = time.perf_counter(), time.process_time()
    if profiler:
        profiler.enable()
    make_report(run, args.out / "report")
    if profiler:
        profiler.disable()
    wall, cpu = time.perf_counter() - start, time.process_time() - cpu
    rows = 4 * args.instances * len(METHODS)
    print(f"report of {rows} rows: {wall:.2f} s wall, {cpu:.2f} s CPU (with pandas' and "
          "matplotlib's imports)")
    if profiler:
        pstats.Stats(profiler).sort_stats("cumulative").print_stats(30)


if __name__ == "__main__":
    main()
