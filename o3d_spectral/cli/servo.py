"""``o3d-spectral servo``: direct 3D visual servoing of a simulated iiwa (paper, Fig. 5)."""

from __future__ import annotations

import argparse
import csv
import json
import os
from pathlib import Path

import numpy as np

from .arguments import seed
from .constants import SUCCESS_ROTATION, SUCCESS_TRANSLATION


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "servo",
        help="servo a simulated KUKA iiwa's eye-in-hand camera to a reference view",
        description="Simulates the paper's second experiment: a KUKA LBR iiwa (pybullet) with "
        "an eye-in-hand depth camera starts at least 20 cm and 30 degrees away from the pose "
        "where a reference cloud of a tabletop was captured, and is driven back by the "
        "spectral control law on whole-scene clouds. Writes per-cycle records, the final "
        "errors and figures; with --trials, one folder per trial and a summary (summary.md, "
        "summary.csv per trial, summary.json the run's figures).",
        epilog="examples: o3d-spectral servo --seed 0 --out out/servo\n"
        "          o3d-spectral servo --seed 0 --trials 30 --out out/servo30",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--seed", type=seed, default=0, help="seed of the first trial")
    parser.add_argument("--out", type=Path, default=Path("out/servo"), help="output folder")
    parser.add_argument("--trials", type=int, default=1,
                        help="number of random starts (seeds SEED, SEED+1, ...)")
    parser.add_argument("--max-time", type=float, default=20.0,
                        help="simulated time limit per run, seconds")
    parser.add_argument("--voxel-size", type=float, default=0.01, help="metres")
    parser.add_argument("--period", type=float, default=0.1, help="control period, seconds")
    parser.add_argument("--workers", type=int, default=1,
                        help="trials run in parallel, one process each (default 1); results "
                        "do not depend on it, controller times do (cores are shared)")
    parser.set_defaults(func=run)


def _trial_row(trial) -> dict:
    run, start = trial.run, trial.start
    final = run.final
    return {
        "seed": trial.seed,
        "objects": " ".join(trial.scene.names),
        "start_translation_m": start.translation,
        "start_rotation_deg": float(np.rad2deg(start.rotation)),
        "start_visible_fraction": start.visible_fraction,
        "final_translation_m": final.translation_error,
        "final_rotation_deg": float(np.rad2deg(final.rotation_error)),
        "success": bool(final.translation_error <= SUCCESS_TRANSLATION
                        and final.rotation_error <= SUCCESS_ROTATION),
        "converged": run.converged,
        "cycles": len(run.cycles),
        "time_s": final.time,
        "limit_violations": run.limit_violations,
        "median_controller_ms": 1000 * run.median_controller_time(),
        "search_cycles": sum(c.searched for c in run.cycles),
    }


def _write_cycles(run, path: Path) -> None:
    with path.open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["time_s", "translation_error_m", "rotation_error_deg",
                         "translation_correction_m", "rotation_correction_deg",
                         "controller_ms", "points", "camera_x", "camera_y", "camera_z",
                         *[f"q{j}" for j in range(len(run.desired_q))],
                         *[f"qdot{j}" for j in range(len(run.desired_q))], "searched"])
        for c in run.cycles:
            writer.writerow([c.time, c.translation_error, np.rad2deg(c.rotation_error),
                             c.translation_correction, np.rad2deg(c.rotation_correction),
                             1000 * c.controller_time, c.points, *c.world_from_camera[:3, 3],
                             *c.q, *c.qdot, c.searched])


def _write_trial(trial, sensor, out: Path, config: dict) -> dict:
    from o3d_spectral.servo import figures

    out.mkdir(parents=True, exist_ok=True)
    row = _trial_row(trial)
    record = {"config": config, **row, "desired_q": trial.run.desired_q.tolist(),
              "start_q": trial.start.q.tolist(),
              "desired_pose": trial.run.desired_pose.tolist()}
    (out / "run.json").write_text(json.dumps(record, indent=2))
    _write_cycles(trial.run, out / "cycles.csv")
    figures.plot_convergence(trial.run, out / "convergence.png")
    figures.plot_trajectory(trial.run, trial.scene, out / "trajectory.png")
    figures.plot_snapshots(trial.run, trial.scene, sensor, out / "snapshots.png",
                           seed=trial.seed)
    return row


def _summary(figures: dict) -> dict:
    """The printed summary: :func:`_figures`' counts and errors, rounded."""
    f = figures
    return {
        "trials": f["trials"],
        "success rate (<= 5 mm and <= 1 deg)": f"{f['successes'] / f['trials']:.0%}",
        "stopped by the gradient test": f["stopped_by_gradient_test"],
        "final translation error, median / max (mm)":
            f"{f['final_translation_mm_median']:.2f} / {f['final_translation_mm_max']:.2f}",
        "final rotation error, median / max (deg)":
            f"{f['final_rotation_deg_median']:.3f} / {f['final_rotation_deg_max']:.3f}",
        "cycles, median / max": f"{f['cycles_median']:.0f} / {f['cycles_max']}",
        "simulated time, median / max (s)":
            f"{f['simulated_s_median']:.1f} / {f['simulated_s_max']:.1f}",
        "joint-limit violations (cycles)": f["limit_violations"],
    }


def _figures(rows: list[dict], cycles: list[tuple[float, bool]]) -> dict:
    """The run's figures as numbers, for ``summary.json``.

    Parameters
    ----------
    rows : list of dict
        One row per trial (``summary.csv``'s).
    cycles : list of (float, bool)
        Every cycle of every trial: its controller time (seconds) and whether it ran the
        global search.

    Returns
    -------
    dict
        Counts over the trials; medians and maxima of their final errors, cycles and
        simulated times (seconds); controller times over all cycles (milliseconds), over
        the law's cycles, and the range over the global search's (seconds).
    """
    t = [1000 * r["final_translation_m"] for r in rows]
    r = [r["final_rotation_deg"] for r in rows]
    law = [s for s, searched in cycles if not searched]
    search = [s for s, searched in cycles if searched]
    return {
        "trials": len(rows),
        "seeds": [min(x["seed"] for x in rows), max(x["seed"] for x in rows)],
        "successes": sum(x["success"] for x in rows),
        "stopped_by_gradient_test": sum(x["converged"] for x in rows),
        "final_translation_mm_median": float(np.median(t)),
        "final_translation_mm_max": float(max(t)),
        "final_rotation_deg_median": float(np.median(r)),
        "final_rotation_deg_max": float(max(r)),
        "cycles_median": float(np.median([x["cycles"] for x in rows])),
        "cycles_max": max(x["cycles"] for x in rows),
        "simulated_s_median": float(np.median([x["time_s"] for x in rows])),
        "simulated_s_max": float(max(x["time_s"] for x in rows)),
        "cycles": len(cycles),
        "search_cycles": len(search),
        "limit_violations": sum(x["limit_violations"] for x in rows),
        "controller_ms_median": 1000 * float(np.median([s for s, _ in cycles])),
        "law_controller_ms_median": 1000 * float(np.median(law)) if law else None,
        "search_controller_s_min": min(search) if search else None,
        "search_controller_s_max": max(search) if search else None,
        "controller_s_total": float(sum(s for s, _ in cycles)),
    }


def write_summary(rows: list[dict], out: Path, cycles: list[tuple[float, bool]]) -> dict:
    """Write ``summary.csv`` (one row per trial), ``summary.json`` (:func:`_figures`) and
    ``summary.md``; return the printed summary."""
    figures = _figures(rows, cycles)
    (out / "summary.json").write_text(json.dumps(figures, indent=2) + "\n")
    with (out / "summary.csv").open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    summary = _summary(figures)
    lines = ["| measure | value |", "| --- | --- |"]
    lines += [f"| {k} | {v} |" for k, v in summary.items()]
    lines += ["", "| seed | start (mm, deg) | final (mm, deg) | success | cycles |",
              "| --- | --- | --- | --- | --- |"]
    lines += [
        f"| {x['seed']} | {1000 * x['start_translation_m']:.0f}, {x['start_rotation_deg']:.1f} "
        f"| {1000 * x['final_translation_m']:.2f}, {x['final_rotation_deg']:.3f} "
        f"| {'yes' if x['success'] else 'no'} | {x['cycles']} |"
        for x in rows
    ]
    (out / "summary.md").write_text("\n".join(lines) + "\n")
    return summary


def _trial_job(job: tuple) -> tuple[dict, list[tuple[float, bool]]]:
    """Run and write one seeded trial in this process: its summary row and, per cycle, the
    controller time (seconds) and whether the cycle ran the global search."""
    from o3d_spectral import servo

    seed, options, folder, config = job
    sensor = servo.Sensor()
    with servo.Arm(world_from_base=servo.WORLD_FROM_BASE) as arm:
        trial = servo.random_trial(seed, arm, sensor, options=options)
    row = _write_trial(trial, sensor, folder, config)
    return row, [(c.controller_time, c.searched) for c in trial.run.cycles]


def _limit_threads(threads: int) -> None:
    """In a trial's worker process: at most ``threads`` threads for its libraries and its
    global searches (:func:`o3d_spectral.common.parallel.resolved_workers`)."""
    os.environ["OMP_NUM_THREADS"] = str(threads)


def run(args: argparse.Namespace) -> int:
    from concurrent.futures import ProcessPoolExecutor
    from multiprocessing import get_context

    from o3d_spectral.common.extras import require_modules

    require_modules("this command", "pybullet", "pybullet_data", "matplotlib", "tqdm")
    from tqdm import tqdm

    from o3d_spectral import servo
    from o3d_spectral.cli import UsageError, results, show_progress

    if args.trials < 1:
        raise UsageError(f"--trials must be >= 1, got {args.trials}")
    if args.workers < 1:
        raise UsageError(f"--workers must be >= 1, got {args.workers}")
    options = servo.ServoOptions(period=args.period, max_time=args.max_time,
                                 voxel_size=args.voxel_size)
    config = {k: str(v) if isinstance(v, Path) else v for k, v in vars(args).items()
              if k != "func"}
    config["options"] = repr(options)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "config.json").write_text(json.dumps(config, indent=2))
    seeds = range(args.seed, args.seed + args.trials)
    jobs = [(seed, options, args.out if args.trials == 1 else args.out / f"seed_{seed:04d}",
             config) for seed in seeds]
    bar = dict(total=len(jobs), desc="trials", unit="run",
               disable=args.trials == 1 or not show_progress(args))
    if args.workers == 1:
        done = [_trial_job(job) for job in tqdm(jobs, **bar)]
    else:
        share = max(1, (os.cpu_count() or 1) // args.workers)  # the cores, shared out
        with ProcessPoolExecutor(max_workers=args.workers, mp_context=get_context("spawn"),
                                 initializer=_limit_threads, initargs=(share,)) as pool:
            done = list(tqdm(pool.map(_trial_job, jobs), **bar))
    rows = [row for row, _ in done]
    cycles = [cycle for _, trial_cycles in done for cycle in trial_cycles]
    out = results()
    median_ms = 1000 * float(np.median([t for t, _ in cycles]))
    for row in rows if args.trials == 1 else []:
        print(f"seed {row['seed']}: start {1000 * row['start_translation_m']:.0f} mm, "
              f"{row['start_rotation_deg']:.1f} deg -> final "
              f"{1000 * row['final_translation_m']:.2f} mm, {row['final_rotation_deg']:.3f} "
              f"deg in {row['time_s']:.1f} s ({row['cycles']} cycles), "
              f"{'converged' if row['converged'] else 'time limit'}", file=out)
    if args.trials > 1:
        for key, value in write_summary(rows, args.out, cycles).items():
            print(f"{key}: {value}", file=out)
    print(f"controller time per cycle (capture excluded), median: {median_ms:.0f} ms", file=out)
    print(f"wrote {args.out}", file=out)
    return 0
