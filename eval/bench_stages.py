"""Benchmark: where the global spectral call spends its time, stage by stage (issue 17).

Runs ``o3d_spectral.registration_spectral_global`` (defaults) and FPFH-RANSAC on the
instances of ``eval/bench_speed.py`` (its tasks, one thread) and times each stage of the
spectral call by wrapping the functions that run it, for the duration of this script:

* prepare: ``registration._start`` (both clouds down-sampled, normals, EGIs, fixed grid);
* SO(3) grid: ``search.egi_rotations`` (the EGI correlation over SO(3) and its peaks;
  once, and once per focused place in a scene);
* sweep: ``search.swept_rotations`` (two views only);
* placements: ``search._placed`` (phase correlations of the candidates, the focused
  searches' included), of which focus: ``search._focused_hypotheses``;
* climbs: the law's climbs of the search (``search.climb``);
* ascent: ``registration.best_ascent``;
* polish + scoring: ``registration._finish`` (the ICP polish, Open3D's evaluation);
* total: the whole call; FPFH-RANSAC: the harness's whole call.

Stages nest (focus is inside placements; the final climb to convergence is in the total
only), so they do not sum to the total. Prints the median of each over each group's
instances as a Markdown table and writes ``stages.csv`` (one row per instance) to
``--out``.

Usage: python eval/bench_stages.py --suites out/suites --out out/bench_stages
       [--limit 12] [--rotations 1] [--groups full dragon_24 ...]
"""

from __future__ import annotations

# isort: off
import bench_speed as speed  # first: it sets one thread before numpy and Open3D load
# isort: on

import argparse
import time
from collections import defaultdict
from collections.abc import Callable
from pathlib import Path

import numpy as np

from o3d_spectral import registration, search

#: (label, module, function) of each timed stage, in the table's order.
STAGES = (
    ("prepare", registration, "_start"),
    ("SO(3) grid", search, "egi_rotations"),
    ("sweep", search, "swept_rotations"),
    ("placements", search, "_placed"),
    ("of which focus", search, "_focused_hypotheses"),
    ("climbs", search, "climb"),
    ("ascent", registration, "best_ascent"),
    ("polish + scoring", registration, "_finish"),
)
COLUMNS = [label for label, _, _ in STAGES] + ["total", "FPFH-RANSAC"]


def timed(clock: defaultdict[str, float], label: str, call: Callable) -> Callable:
    """``call`` adding its run time (seconds) to ``clock[label]``; a call inside another
    of the same label is counted once, by the outer one."""
    depth = [0]

    def wrapper(*args, **kwargs):
        depth[0] += 1
        start = time.perf_counter()
        try:
            return call(*args, **kwargs)
        finally:
            depth[0] -= 1
            if depth[0] == 0:
                clock[label] += time.perf_counter() - start

    return wrapper


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--suites", type=Path, help="folder of the four suites (skipped if absent)")
    parser.add_argument("--out", type=Path, default=Path("out/bench_stages"))
    parser.add_argument("--limit", type=int, default=12, help="instances per group at most")
    parser.add_argument("--rotations", type=int, default=1, help="random rotations per real case")
    parser.add_argument("--groups", nargs="+", choices=speed.CONDITIONS + speed.real.GROUPS,
                        default=list(speed.CONDITIONS + speed.real.GROUPS))
    args = parser.parse_args()
    groups = [g for g in args.groups if args.suites is not None or g not in speed.CONDITIONS]

    clock: defaultdict[str, float] = defaultdict(float)
    for label, module, name in STAGES:
        setattr(module, name, timed(clock, label, getattr(module, name)))

    rows, lines, warmed = [], [], False
    for group in groups:
        if group in speed.CONDITIONS:
            tasks = list(speed.suite_tasks(args.suites, group, args.limit))
        else:
            tasks = list(speed.real_tasks(group, args.rotations, args.limit))
        if not warmed and tasks:  # untimed: FFT plans, caches, compiled kernels
            speed.spectral_global(tasks[0])
            speed.fpfh_ransac(tasks[0])
            warmed = True
        times = []
        for task in tasks:
            clock.clear()
            start = time.perf_counter()
            speed.spectral_global(task)
            clock["total"] = time.perf_counter() - start
            start = time.perf_counter()
            speed.fpfh_ransac(task)
            clock["FPFH-RANSAC"] = time.perf_counter() - start
            times.append([clock[c] for c in COLUMNS])
            rows.append({"group": group, "instance": task.name,
                         **{c: clock[c] for c in COLUMNS}})
        if times:
            median = np.median(np.array(times), axis=0)
            cells = " | ".join(f"{m:.3f}" for m in median)
            lines.append(f"| {group} ({len(tasks)}) | {cells} |")
            print(lines[-1], flush=True)

    table = "\n".join(["| group | " + " | ".join(COLUMNS) + " |",
                       "|" + " --- |" * (len(COLUMNS) + 1), *lines])
    args.out.mkdir(parents=True, exist_ok=True)
    speed.write_csv(args.out / "stages.csv", rows)
    print(table)
    print(f"wrote {args.out / 'stages.csv'}")


if __name__ == "__main__":
    main()
