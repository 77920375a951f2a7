"""Benchmark: the dense search against the adaptive one and FPFH-RANSAC, success and time.

On the instances of ``eval/bench_speed.py`` (its groups and options), runs on each:

* ``adaptive``: ``registration_spectral_global`` with ``GlobalSearchOption(rotations=
  "adaptive")``;
* ``escalating``: the same at its defaults on the CPU (``rotations="escalating"``: the
  adaptive search, and the dense one too where its pose may be wrong);
* ``dense``: the same with ``GlobalSearchOption(rotations="dense")`` (4608 rotations), and
  ``dense_N`` for each ``N`` of ``--budgets`` (``dense_rotations=N``);
* ``lean``: the lean FPFH-RANSAC that every ratio of ``bench_speed.py`` divides by
  (``fpfh_ransac_lean``: the tutorial's features and RANSAC, 100000 iterations at
  confidence 0.999, its ICP on both clouds thinned to half the voxel), and ``lean_I_C``
  for each ``I:C`` of ``--ransac`` (RANSAC stopped at ``I`` iterations, confidence ``C``).

Each call is timed once, the variants in turn on each instance, with ``time.perf_counter``
around the call only; one untimed call of each kind first warms caches. One thread for
every method (``--all-cores``: the spectral calls on every core, FPFH-RANSAC's Open3D on
its own). Success as ``bench_speed.py`` scores it (symmetry-aware, 5 degrees and 1 cm).

Reports per group and variant: n, success, median seconds (every call, right or wrong),
and the dense sweep's median seconds (the dense calls' stage ``sweep``, the escalating
calls' ``dense_sweep``); writes ``rows.csv`` (each spectral call's ``confidence``, ``fit``
and ``fitness`` beside its time and errors; where the escalating call escalated, its
second pass returns the dense call's pose, so the adaptive and dense rows hold both of
its candidates),
``summary.csv`` and ``summary.md`` to ``--out``, and with ``--figure`` the success of each
variant against its median time (a Pareto view in the manner of Deep Global
Registration's), one panel per kind of problem as ``frontier.png`` and one per group as
``frontier_groups.png``.

Usage: python eval/bench_dense.py --suites SUITES --out out/bench_dense [--groups ...]
       [--limit 6] [--rotations 1] [--budgets 1000 2304] [--ransac 1000:0.99 10000:0.999]
       [--all-cores] [--figure]
       python eval/bench_dense.py --figure-from out/bench_dense/summary.csv --out DIR
"""

from __future__ import annotations

# isort: off
import bench_speed as speed  # first: it sets one thread before numpy and Open3D load
# isort: on

import argparse
import csv
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

import o3d_spectral
from o3d_spectral.harness import tutorial
from o3d_spectral.harness.writers import write_rows

#: The kinds of problem a group belongs to, for the figure's panels.
KINDS = {
    "views": ("full", "partial", "occluded", "ycbv_crop"),
    "scenes": ("cluttered", "crop_in_scene", "wide", "ycbv_frame"),
    "scan pairs": ("turntable_45", "turntable_90", "turntable_135", "dragon_unoriented",
                   "dragon_24", "dragon_48", "dragon_72", "dragon_96", "dragon_120"),
    "model into scan": ("dragon_model",),
}


def spectral(rotations: str, count: int | None = None):
    """A spectral call of a task with the search's ``rotations`` (and ``dense_rotations``)."""
    settings = {} if count is None else {"dense_rotations": count}
    workers = 1 if speed.ONE_THREAD else None
    sweep_stage = "dense_sweep" if rotations == "escalating" else "sweep"

    def call(task: speed.Task) -> tuple[np.ndarray, dict]:
        search = o3d_spectral.GlobalSearchOption(rotations=rotations, workers=workers,
                                                 **settings)
        result = o3d_spectral.registration_spectral_global(task.source, task.target,
                                                           task.voxel, search=search)
        return np.asarray(result.transformation), {
            "sweep_s": result.stage_times.get(sweep_stage, 0.0), "confidence": result.confidence,
            "fit": result.fit, "fitness": result.fitness}

    return call


def lean_ransac(max_iteration: int, confidence: float):
    """The lean FPFH-RANSAC of a task, its RANSAC stopped at ``max_iteration`` iterations
    or ``confidence``."""
    def call(task: speed.Task) -> tuple[np.ndarray, dict]:
        match = tutorial.ransac_matcher(task.voxel, max_iteration=max_iteration,
                                        confidence=confidence)
        T = tutorial.global_then_refine(task.source, task.target, task.voxel, task.seed,
                                        match, lean=True)
        return T, {"sweep_s": float("nan"), "confidence": float("nan"), "fit": float("nan"),
                   "fitness": float("nan")}

    return call


def variants(budgets: list[int], ransac: list[str]) -> dict[str, object]:
    """The calls compared, by name (the module docstring)."""
    calls = {"adaptive": spectral("adaptive"), "escalating": spectral("escalating"),
             "dense": spectral("dense")}
    calls |= {f"dense_{n}": spectral("dense", n) for n in budgets}
    defaults = tutorial.RANSAC
    calls["lean"] = lean_ransac(defaults["max_iteration"], defaults["confidence"])
    for pair in ransac:
        iterations, confidence = pair.split(":")
        calls[f"lean_{iterations}_{confidence}"] = lean_ransac(int(iterations),
                                                               float(confidence))
    return calls


def run_task(task: speed.Task, calls: dict[str, object]) -> list[dict]:
    """One row per variant: its time and the score of its pose."""
    rows = []
    for name, call in calls.items():
        start = time.perf_counter()
        T, extra = call(task)
        seconds = time.perf_counter() - start
        rot, tra, success = task.score(T)
        rows.append({"group": task.group, "instance": task.name, "variant": name,
                     "seconds": seconds, "rotation_error_deg": rot,
                     "translation_error_m": tra, "success": bool(success), **extra})
    return rows


def summarise(rows: list[dict], groups: list[str], names: list[str]) -> list[dict]:
    """Per group and variant: n, success, median seconds, median sweep seconds."""
    out = []
    for group in groups:
        for name in names:
            picked = [r for r in rows if r["group"] == group and r["variant"] == name]
            if picked:
                out.append({
                    "group": group, "variant": name, "n": len(picked),
                    "success": float(np.mean([r["success"] for r in picked])),
                    "median_s": float(np.median([r["seconds"] for r in picked])),
                    "sweep_median_s": float(np.median([r["sweep_s"] for r in picked])),
                })
    return out


def markdown(summary: list[dict], names: list[str]) -> str:
    """The summary as one row per group: each variant's success and median seconds."""
    head = "| group | n | " + " | ".join(f"{n} success | {n} median s" for n in names) + " |"
    lines = [head, "|" + " --- |" * (2 + 2 * len(names))]
    for group in dict.fromkeys(s["group"] for s in summary):
        cells = {s["variant"]: s for s in summary if s["group"] == group}
        n = next(iter(cells.values()))["n"]
        lines.append(f"| {group} | {n} | " + " | ".join(
            f"{100 * cells[v]['success']:.0f}% | {cells[v]['median_s']:.3f}" for v in names
        ) + " |")
    return "\n".join(lines)


def figure(summary: list[dict], path: Path, panels: dict[str, tuple[str, ...]]) -> None:
    """Success against median time, one panel per entry of ``panels`` (its groups' calls
    pooled, the median of their medians), one curve per family: the adaptive search, the
    escalating one (the CPU's default), the dense search at each count, the lean
    FPFH-RANSAC at each setting, each point labelled."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter, ScalarFormatter

    titles = [t for t, groups in panels.items() if any(s["group"] in groups for s in summary)]
    columns = min(len(titles), 6)
    rows = -(-len(titles) // columns)
    fig, axes = plt.subplots(rows, columns, figsize=(3.6 * columns, 3.3 * rows), squeeze=False)
    for ax in axes.flat[len(titles):]:
        ax.set_visible(False)
    for ax, title in zip(axes.flat, titles, strict=False):
        picked = [s for s in summary if s["group"] in panels[title]]
        for family, marker, label in (("adaptive", "o", "spectral, adaptive"),
                                      ("escalating", "D", "spectral, escalating"),
                                      ("dense", "s", "spectral, dense"),
                                      ("lean", "^", "lean FPFH-RANSAC")):
            points = []
            for name in sorted({s["variant"] for s in picked
                                if s["variant"].startswith(family)}):
                chosen = [s for s in picked if s["variant"] == name]
                n = np.array([float(s["n"]) for s in chosen])
                points.append((float(np.median([float(s["median_s"]) for s in chosen])),
                               100 * float(np.average([float(s["success"]) for s in chosen],
                                                      weights=n)), name))
            points.sort()
            if points:
                x, y, _ = zip(*points, strict=True)
                ax.plot(x, y, marker=marker, label=label)
                for xi, yi, name in points:
                    ax.annotate(name.removeprefix(family).strip("_") or "default", (xi, yi),
                                textcoords="offset points", xytext=(3, 3), fontsize=6)
        ax.set_xscale("log")
        ax.xaxis.set_major_formatter(ScalarFormatter())
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_title(title)
        ax.set_xlabel("median seconds per call")
        ax.set_ylabel("success (%)")
        ax.grid(True, alpha=0.3)
    axes[0][0].legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def figures(summary: list[dict], out: Path) -> None:
    """``frontier.png``, a panel per kind of problem, and ``frontier_groups.png``, a panel
    per group."""
    figure(summary, out / "frontier.png", KINDS)
    groups = dict.fromkeys(s["group"] for s in summary)
    figure(summary, out / "frontier_groups.png", {g: (g,) for g in groups})


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    speed.add_task_arguments(parser, limit=6, rotations=1)
    parser.add_argument("--out", type=Path, default=Path("out/bench_dense"))
    parser.add_argument("--budgets", type=int, nargs="*", default=[],
                        help="more dense_rotations counts to run")
    parser.add_argument("--ransac", nargs="*", default=[],
                        help="more RANSAC settings, ITERATIONS:CONFIDENCE")
    parser.add_argument("--all-cores", action="store_true",
                        help="every method on every core (default: one thread)")
    parser.add_argument("--figure", action="store_true",
                        help="write frontier.png and frontier_groups.png")
    parser.add_argument("--figure-from", type=Path,
                        help="only draw the figures from a stored summary.csv")
    args = parser.parse_args()
    if args.figure_from is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        with open(args.figure_from, newline="") as f:
            figures(list(csv.DictReader(f)), args.out)
        return
    if any(n < 1 for n in args.budgets):
        parser.error("--budgets must be positive counts")
    groups = speed.chosen_groups(args)
    tasks = speed.chosen_tasks(parser, args, groups)
    calls = variants(args.budgets, args.ransac)
    for call in calls.values():  # warm-up, untimed
        call(tasks[0])
    rows: list[dict] = []
    for task in tqdm(tasks, desc="bench_dense", unit="inst"):
        rows += run_task(task, calls)
    names = list(calls)
    summary = summarise(rows, groups, names)
    table = markdown(summary, names)
    args.out.mkdir(parents=True, exist_ok=True)
    write_rows(args.out / "rows.csv", rows)
    write_rows(args.out / "summary.csv", summary)
    threads = "one thread" if speed.ONE_THREAD else "every core"
    (args.out / "summary.md").write_text(f"{table}\n\n{threads}; each call timed once\n")
    if args.figure:
        figures(summary, args.out)
    print(table)


if __name__ == "__main__":
    main()
