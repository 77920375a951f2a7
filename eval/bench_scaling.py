"""Benchmark: how the global spectral call and FPFH-RANSAC scale.

One case, the YCB-Video mug's model points against the whole frame (``ycbv_frame_025_mug``
of ``o3d_spectral.harness.real``; source turned by the seeded rotation 0), one thread, each
call timed with ``time.perf_counter`` around the call only (as ``eval/bench_speed.py``,
whose two calls it reuses: FPFH-RANSAC estimates the target's normals inside its timed
call). The median of ``--repeats`` calls per point (1 by default: each point timed once).

* against input points: the frame (68,443 points as bundled, down-sampled at 2 mm) is
  resampled to each of ``--points`` (default 10k, 100k, 1M): a random subset without
  replacement when it has more points, otherwise all of them plus random duplicates, each
  duplicate jittered by isotropic Gaussian noise of 0.5 mm (so none coincide); voxel 8 mm.
* against grid size: the bundled frame at each of ``--voxels`` (default 16, 12, 10, 8 mm);
  the x axis is the cell count of the FFT grid of the global phase correlation,
  ``prod(TargetGrid.fft_shape(grid.box, grid.moving_box(radius, centroid)))`` from
  ``SpectralStepper(target, voxel).grid`` and the source's ``MovingCloud``.

Writes ``scaling.csv`` to ``--out`` and the figure ``--figure`` (log-log, two panels).

Usage: python eval/bench_scaling.py [--points 10000 100000 1000000] [--voxels 0.016 0.008]
       [--repeats 1] [--out out/bench_scaling] [--figure docs/img/time_vs_points.png]
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import csv  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import open3d as o3d  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_speed import CALLS, METHODS, Task  # noqa: E402  (sets one Open3D thread)

from o3d_spectral import SpectralStepper  # noqa: E402
from o3d_spectral.harness import real  # noqa: E402
from o3d_spectral.harness.writers import write_figure  # noqa: E402

CASE = "ycbv_frame_025_mug"
JITTER = 0.0005
LABELS = {"spectral_global": "spectral global", "fpfh_ransac_lean": "lean FPFH-RANSAC",
          "fpfh_ransac": "tutorial FPFH-RANSAC"}


def resampled(points: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` points: a subset without replacement, or all plus jittered duplicates."""
    if n <= len(points):
        return points[rng.choice(len(points), n, replace=False)]
    extra = points[rng.integers(len(points), size=n - len(points))]
    return np.vstack([points, extra + rng.normal(scale=JITTER, size=extra.shape)])


def fft_cells(task: Task) -> int:
    """Cells of the global phase correlation's FFT grid at ``task.voxel``."""
    stepper = SpectralStepper(task.target, task.voxel)
    moving = stepper.moving(task.source)
    box = stepper.grid.moving_box(moving.radius, moving.centroid)
    return int(np.prod(stepper.grid.fft_shape(stepper.grid.box, box), dtype=np.int64))


def timed(task: Task, repeats: int) -> dict:
    out = {}
    for method in METHODS:
        times = []
        for _ in range(repeats):
            start = time.perf_counter()
            CALLS[method](task)
            times.append(time.perf_counter() - start)
        out[method] = float(np.median(times))
    return out


def measure(sweep: str, task: Task, repeats: int) -> dict:
    row = {"sweep": sweep, "voxel_m": task.voxel, "target_points": len(task.target.points),
           "fft_cells": fft_cells(task)}
    row |= {f"{method}_s": seconds for method, seconds in timed(task, repeats).items()}
    print(", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}"
                    for k, v in row.items()), flush=True)
    return row


def figure(rows: list[dict], path: Path) -> None:
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for ax, sweep, key, label in (
        (axes[0], "points", "target_points", "target points (voxel 8 mm)"),
        (axes[1], "voxel", "fft_cells", "FFT grid cells (labels: voxel, mm)"),
    ):
        picked = sorted((r for r in rows if r["sweep"] == sweep), key=lambda r: r[key])
        for method in METHODS:
            ax.plot([r[key] for r in picked], [r[f"{method}_s"] for r in picked], "o-",
                    label=LABELS[method])
        if sweep == "voxel":
            for r in picked:
                ax.annotate(f"{1000 * r['voxel_m']:g}", (r[key], r[f"{METHODS[0]}_s"]),
                            textcoords="offset points", xytext=(4, 4), fontsize=8)
        ax.set(xscale="log", yscale="log", xlabel=label, ylabel="time per call (s)")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend()
    fig.suptitle(f"{CASE}: time per call, one thread")
    write_figure(fig, path)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, nargs="+", default=[10_000, 100_000, 1_000_000])
    parser.add_argument("--voxels", type=float, nargs="+", default=[0.016, 0.012, 0.010, 0.008])
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--out", type=Path, default=Path("out/bench_scaling"))
    parser.add_argument("--figure", type=Path, default=Path("docs/img/time_vs_points.png"))
    args = parser.parse_args()

    case = next(c for c in real.load_cases(["ycbv_frame"]) if c.name == CASE)
    case, _ = real.randomly_rotated(case, 0)
    scene = np.asarray(case.target.points)
    rng = np.random.default_rng(0)
    base = Task("scaling", CASE, case.source, case.target, 0.008, 0, None)
    for method in METHODS:  # warm-up, untimed
        CALLS[method](base)

    rows = []
    for n in args.points:
        target = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(resampled(scene, n, rng)))
        task = Task("scaling", CASE, case.source, target, 0.008, 0, None)
        rows.append(measure("points", task, args.repeats))
    for voxel in args.voxels:
        task = Task("scaling", CASE, case.source, case.target, voxel, 0, None)
        rows.append(measure("voxel", task, args.repeats))

    args.out.mkdir(parents=True, exist_ok=True)
    with open(args.out / "scaling.csv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    figure(rows, args.figure)
    print(f"wrote {args.out / 'scaling.csv'} and {args.figure}")


if __name__ == "__main__":
    main()
