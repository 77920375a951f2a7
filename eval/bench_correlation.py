"""Benchmark: the dense search's cost per rotation and its gain from more workers.

For the first instance of each group of ``eval/bench_speed.py``, prepares the clouds as
the global call does, then, on one worker and on ``--workers`` workers in turn,
``--repeats`` times (the median kept):

* times :class:`o3d_spectral.correlation.BatchedCorrelation` on the two grids the dense
  search ranks on (:mod:`o3d_spectral.search.dense`: the coarse one, where the moving
  cloud spans about ``COARSE_SPAN`` cells, and the placement's), over ``--count`` even
  rotations: milliseconds per rotation;
* times the whole dense sweep (:func:`o3d_spectral.search.dense.dense_candidates`,
  ``--dense-count`` rotations, 4608 as the search's default): seconds.

Reports each, the gain of the workers over one, and the share of the one-worker time that
did not run in parallel as that gain implies (Amdahl's law: ``(W / gain - 1) / (W - 1)``
for ``W`` workers). The process's CPU time tells the two causes apart: *busy* is the share
of the ``W`` workers' wall time they ran (CPU time over ``W`` times the wall time; what is
left they waited: for the last run, or on the steps between correlations), and *CPU per
rotation* the CPU time the workers spent over what one worker spent on the same work (over
1: each core did the same work slower, sharing the memory and caches). The gain is ``W``
times the busy share with ``W`` workers over that with one, over that ratio.

Usage: python eval/bench_correlation.py --suites SUITES --out out/bench_correlation
       [--groups dragon_96 turntable_90 ...] [--count 512] [--workers 2]
"""

from __future__ import annotations

# isort: off
import bench_speed as speed  # first: it sets one thread before numpy and Open3D load
# isort: on

import argparse
import time
from pathlib import Path
from typing import NamedTuple

import numpy as np

from o3d_spectral import run as runs
from o3d_spectral.harness.writers import write_rows
from o3d_spectral.search.candidates import span_factor, turned_correlation
from o3d_spectral.search.dense import COARSE_SPAN, dense_candidates
from o3d_spectral.search.placement import placement_factor
from o3d_spectral.search.situation import situation
from o3d_spectral.spectra import so3


def serial_share(gain: float, workers: int) -> float:
    """The share of one worker's time that does not run in parallel, as ``gain`` on
    ``workers`` implies (Amdahl's law)."""
    return max(0.0, (workers / gain - 1.0) / (workers - 1.0))


class Timing(NamedTuple):
    """Median wall and CPU seconds (the whole process's) of one piece of work, on one
    worker and on ``workers``."""

    wall_one: float
    wall_many: float
    cpu_one: float
    cpu_many: float

    def row(self, workers: int, scale: float = 1.0) -> dict:
        """The gain and its parts (see the module docstring); times times ``scale``."""
        gain = self.wall_one / self.wall_many
        return {"one": scale * self.wall_one, "many": scale * self.wall_many, "gain": gain,
                "serial_share": serial_share(gain, workers),
                "busy_one": self.cpu_one / self.wall_one,
                "busy_many": self.cpu_many / (workers * self.wall_many),
                "cpu_ratio": self.cpu_many / self.cpu_one}


def alternated(work, workers: int, repeats: int) -> Timing:
    """Median wall and CPU seconds of ``work(w)`` on one worker and on ``workers``, run
    in turn."""
    wall: dict[int, list[float]] = {1: [], workers: []}
    cpu: dict[int, list[float]] = {1: [], workers: []}
    for _ in range(repeats):
        for w in (1, workers):
            start, start_cpu = time.perf_counter(), time.process_time()
            work(w)
            wall[w].append(time.perf_counter() - start)
            cpu[w].append(time.process_time() - start_cpu)
    return Timing(*(float(np.median(d[k])) for d in (wall, cpu) for k in (1, workers)))


def measure(
    task: speed.Task, count: int, dense_count: int, workers: int, repeats: int
) -> list[dict]:
    """Rows for ``task``: the dense search's two grids, then its whole sweep."""
    run = runs.start(task.source, task.target, task.voxel, np.eye(4), None, None, None)
    stepper, moving = run.stepper, run.moving
    two_scans = situation(stepper, moving).two_scans
    fine = placement_factor(stepper.voxel_size, moving.radius, two_scans=two_scans)
    coarse = span_factor(stepper.voxel_size, moving.radius, COARSE_SPAN)
    rotations = so3.uniform_rotations(count)
    rows = []
    for name, factor in (("coarse", coarse), ("fine", fine)):
        correlation, cloud = turned_correlation(stepper, moving, factor)
        correlation.peaks(cloud, rotations[:8], workers)  # warm-up
        timing = alternated(lambda w, c=correlation, m=cloud: c.peaks(m, rotations, w),
                            workers, repeats)
        rows.append({"group": task.group, "instance": task.name, "what": f"{name} grid",
                     "voxels": factor, "fft": "x".join(str(n) for n in correlation.shape),
                     "unit": "ms/rotation", **timing.row(workers, 1e3 / count)})
    timing = alternated(lambda w: dense_candidates(stepper, moving, dense_count,
                                                   two_scans=two_scans, workers=w),
                        workers, repeats)
    rows.append({"group": task.group, "instance": task.name, "what": "dense sweep",
                 "voxels": float("nan"), "fft": "", "unit": "s", **timing.row(workers)})
    return rows


def markdown(rows: list[dict], workers: int) -> str:
    head = (f"| group | what | voxels | FFT | 1 worker | {workers} workers | unit | gain "
            f"| not in parallel | busy, 1 | busy, {workers} | CPU per rotation |")
    lines = [head, "|" + " --- |" * 12]
    for r in rows:
        voxels = "" if np.isnan(r["voxels"]) else f"{r['voxels']:g}"
        lines.append(f"| {r['group']} | {r['what']} | {voxels} | {r['fft']} | {r['one']:.3f} "
                     f"| {r['many']:.3f} | {r['unit']} | {r['gain']:.2f}x "
                     f"| {100 * r['serial_share']:.0f}% | {100 * r['busy_one']:.0f}% "
                     f"| {100 * r['busy_many']:.0f}% | {r['cpu_ratio']:.2f}x |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    speed.add_task_arguments(parser, limit=1, rotations=1)
    parser.add_argument("--out", type=Path, default=Path("out/bench_correlation"))
    parser.add_argument("--count", type=int, default=512,
                        help="even rotations correlated per timed run")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--dense-count", type=int, default=4608,
                        help="rotations of the dense sweep timed whole")
    args = parser.parse_args()
    groups = speed.chosen_groups(args)
    rows = []
    for group in groups:
        tasks = speed.group_tasks(group, args.suites, 1, 1)
        if tasks:
            rows += measure(tasks[0], args.count, args.dense_count, args.workers,
                            args.repeats)
            print(f"{group}: done", flush=True)
    table = markdown(rows, args.workers)
    args.out.mkdir(parents=True, exist_ok=True)
    write_rows(args.out / "rows.csv", rows)
    (args.out / "summary.md").write_text(table + "\n")
    print(table)


if __name__ == "__main__":
    main()
