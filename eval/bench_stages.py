"""Benchmark: where the global spectral call spends its time, stage by stage.

Runs ``o3d_spectral.registration_spectral_global`` (defaults) and lean FPFH-RANSAC on the
instances of ``eval/bench_speed.py`` (its tasks, one thread) and reads each stage's time
from the call's own record, ``result.stage_times`` (:mod:`o3d_spectral.common.stages`): prepare,
candidates (the SO(3) correlation, the placements and, in a scene, the focused searches),
confirm, sweep (two scans not confirmed by the other candidates), climbs, ascent (two
scans only), polish (the ICP polish and Open3D's scoring). A stage a call skipped counts
0 s; the stages sum to the call's time. Prints the median of each over each group's
instances, the share of calls confirmed early, as a Markdown table, and writes
``stages.csv`` (one row per instance) to ``--out``.

Usage: python eval/bench_stages.py --suites out/suites --out out/bench_stages
       [--limit 12] [--rotations 1] [--groups full dragon_24 ...]
"""

from __future__ import annotations

# isort: off
import bench_speed as speed  # first: it sets one thread before numpy and Open3D load
# isort: on

import argparse
import time
from pathlib import Path

import numpy as np

import o3d_spectral
from o3d_spectral.common.stages import GLOBAL_STAGES
from o3d_spectral.harness.writers import write_rows

REFERENCE_COLUMN = "lean FPFH-RANSAC"
COLUMNS = [*GLOBAL_STAGES, "total", REFERENCE_COLUMN]


def staged(task: speed.Task) -> tuple[dict[str, float], bool]:
    """The spectral call's stage times (seconds, every stage of :data:`GLOBAL_STAGES`) and
    whether it was confirmed early."""
    start = time.perf_counter()
    result = o3d_spectral.registration_spectral_global(
        task.source, task.target, task.voxel, search=o3d_spectral.GlobalSearchOption(workers=1))
    times = {stage: result.stage_times.get(stage, 0.0) for stage in GLOBAL_STAGES}
    times["total"] = time.perf_counter() - start
    return times, result.confirmed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    speed.add_task_arguments(parser, limit=12, rotations=1)
    parser.add_argument("--out", type=Path, default=Path("out/bench_stages"))
    args = parser.parse_args()
    groups = speed.chosen_groups(args)

    rows, lines, warmed = [], [], False
    for group in groups:
        tasks = speed.group_tasks(group, args.suites, args.rotations, args.limit)
        if not warmed and tasks:  # untimed: FFT plans, caches, compiled kernels
            speed.spectral_global(tasks[0])
            speed.CALLS[speed.REFERENCE](tasks[0])
            warmed = True
        times, confirmed = [], 0
        for task in tasks:
            clock, early = staged(task)
            start = time.perf_counter()
            speed.CALLS[speed.REFERENCE](task)
            clock[REFERENCE_COLUMN] = time.perf_counter() - start
            confirmed += early
            times.append([clock[c] for c in COLUMNS])
            rows.append({"group": group, "instance": task.name, "confirmed": early,
                         **{c: clock[c] for c in COLUMNS}})
        if times:
            median = np.median(np.array(times), axis=0)
            cells = " | ".join(f"{m:.3f}" for m in median)
            lines.append(f"| {group} ({len(tasks)}) | {cells} | {confirmed / len(tasks):.0%} |")
            print(lines[-1], flush=True)

    table = "\n".join(["| group | " + " | ".join(COLUMNS) + " | confirmed |",
                       "|" + " --- |" * (len(COLUMNS) + 2), *lines])
    args.out.mkdir(parents=True, exist_ok=True)
    write_rows(args.out / "stages.csv", rows)
    print(table)
    print(f"wrote {args.out / 'stages.csv'}")


if __name__ == "__main__":
    main()
