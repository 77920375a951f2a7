"""Benchmark: time of the global spectral call and FPFH-RANSAC against a scene's width.

One view of one object (``--object``, the power drill by default) against reconstructed
tabletops ``--widths`` metres wide (0.5, 1, 2, 4 m by default; half as deep, at least
0.5 m; 8 objects per square metre: ``o3d_spectral.synthetic.wide``), 8 mm voxels, one
thread, both methods timed on the same instances (``--seeds`` scenes per width, seeded
100, 101, ...) in the same run as ``eval/bench_speed.py`` times them. Plots the median
time of each method against the scene's points, with a line through the first point of
slope one (time proportional to the points), and writes ``width.csv``.

Usage: python eval/bench_width.py [--widths 0.5 1 2 4] [--seeds 3]
       [--out out/bench_width] [--figure docs/img/time_vs_width.png]
       python eval/bench_width.py --plot out/bench_width/width.csv
"""

from __future__ import annotations

# isort: off
import bench_speed as speed  # first: it sets one thread before numpy and Open3D load
# isort: on

import argparse
import csv
import time
from pathlib import Path

import matplotlib
import matplotlib.ticker

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from o3d_spectral.harness.metrics import instance_metrics  # noqa: E402
from o3d_spectral.harness.writers import write_figure, write_rows  # noqa: E402
from o3d_spectral.synthetic.wide import wide_scene_instance  # noqa: E402

LABELS = {"spectral_global": "spectral global", "fpfh_ransac_lean": "lean FPFH-RANSAC",
          "fpfh_ransac": "tutorial FPFH-RANSAC"}


def measure(name: str, width: float, seed: int) -> list[dict]:
    """Both methods on one scene: seconds and success of each."""
    instance = wide_scene_instance(name, width, np.random.default_rng(seed))
    task = speed.Task("wide", f"{name}_{width}_{seed}", instance.source, instance.target,
                      speed.SUITE_VOXEL, seed, None)
    rows = []
    for method in speed.METHODS:
        start = time.perf_counter()
        T, _ = speed.CALLS[method](task)
        seconds = time.perf_counter() - start
        rows.append({"width_m": width, "seed": seed, "method": method,
                     "scene_points": len(instance.target.points), "seconds": seconds,
                     "success": bool(instance_metrics(T, instance)["success"])})
    return rows


def figure(rows: list[dict], path: Path) -> None:
    fig, ax = plt.subplots(figsize=(5.5, 4))
    for method in speed.METHODS:
        widths = sorted({r["width_m"] for r in rows})
        points = [np.median([r["scene_points"] for r in rows if r["width_m"] == w])
                  for w in widths]
        seconds = [np.median([r["seconds"] for r in rows
                              if r["width_m"] == w and r["method"] == method]) for w in widths]
        ax.loglog(points, seconds, "o-", label=LABELS[method])
        for w, x, y in zip(widths, points, seconds, strict=True):
            ax.annotate(f"{w:g} m", (x, y), textcoords="offset points", xytext=(4, -10),
                        fontsize=8)
        if method == speed.METHODS[0]:
            ax.loglog(points, seconds[0] * np.asarray(points) / points[0], "k:", lw=1,
                      label="proportional to the points")
    ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    ax.set_xlabel("scene points")
    ax.set_ylabel("median seconds per call (one thread)")
    ax.set_title("One object's view against a tabletop of growing width")
    ax.legend(fontsize=8)
    write_figure(fig, path)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--widths", type=float, nargs="+", default=[0.5, 1.0, 2.0, 4.0])
    parser.add_argument("--seeds", type=int, default=3, help="scenes per width")
    parser.add_argument("--object", default="power_drill")
    parser.add_argument("--out", type=Path, default=Path("out/bench_width"))
    parser.add_argument("--figure", type=Path, default=Path("docs/img/time_vs_width.png"))
    parser.add_argument("--plot", type=Path, metavar="CSV",
                        help="only draw the figure from an earlier run's width.csv")
    args = parser.parse_args()
    if args.plot is not None:
        with open(args.plot, newline="") as handle:
            rows = [{**r, "width_m": float(r["width_m"]), "seconds": float(r["seconds"]),
                     "scene_points": int(r["scene_points"])} for r in csv.DictReader(handle)]
        figure(rows, args.figure)
        return
    measure(args.object, args.widths[0], 100)  # untimed warm-up: plans, caches, kernels
    rows = []
    for width in args.widths:
        for seed in range(100, 100 + args.seeds):
            rows += measure(args.object, width, seed)
            print(rows[-2], rows[-1], flush=True)
    args.out.mkdir(parents=True, exist_ok=True)
    write_rows(args.out / "width.csv", rows)
    figure(rows, args.figure)
    print(f"wrote {args.out / 'width.csv'} and {args.figure}")


if __name__ == "__main__":
    main()
