"""Benchmark: what each setting of the global call buys in time, and costs in success.

Runs ``o3d_spectral.registration_spectral_global`` on the instances of
``eval/bench_speed.py`` (its tasks, one thread) at its defaults and with one setting
changed at a time (:data:`SETTINGS`): the voxel one and a half times larger, the polish
left out or without its wide pass, and the search's options a user would lower to trade
success for time. For each setting and each kind of problem (views, scenes, scan pairs,
real YCB-Video data), reports the median over the calls of the call's time over the same
instance's time at the defaults and the ratio of their total times (what a batch of such
calls saves), the calls right (success as ``bench_speed.py`` scores
it: 5 degrees and 1 cm), those lost and won against the defaults, and the median rotation
error of the right calls (degrees). Prints a Markdown table and writes ``rows.csv`` (one
row per call) and ``summary.csv`` to ``--out``.

Each call is timed once, the defaults and the settings in turn on each instance (so that a
drift of the machine falls on all), after one untimed call at the defaults on the same
instance (the first call on new clouds pays for caches the others find filled): read a
time ratio to within about 10%.

Usage: python eval/bench_settings.py --suites out/suites --out out/bench_settings
       [--limit 6] [--rotations 1] [--groups full dragon_24 ...] [--settings defaults ...]
       python eval/bench_settings.py --from-rows out/bench_settings/rows.csv --out DIR
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

import o3d_spectral
from o3d_spectral import GlobalSearchOption, RefinementOption
from o3d_spectral.harness.writers import write_rows

#: What a setting changes in the call: the voxel's factor, and the keyword arguments of
#: ``registration_spectral_global`` (its ``search`` always on one worker).
Setting = tuple[float, dict]


def _search(**changed: object) -> dict:
    return {"search": GlobalSearchOption(workers=1, **changed)}


#: The settings measured, by name: the defaults, then one change each.
SETTINGS: dict[str, Setting] = {
    "defaults": (1.0, _search()),
    "voxel_size x 1.5": (1.5, _search()),
    "refinement=None": (1.0, {**_search(), "refinement": None}),
    "RefinementOption(wide_distance=None)": (
        1.0, {**_search(), "refinement": RefinementOption(wide_distance=None)}),
    "RefinementOption(cell=0.5)": (
        1.0, {**_search(), "refinement": RefinementOption(cell=0.5)}),
    "hypotheses=16": (1.0, _search(hypotheses=16)),
    "climbs=2": (1.0, _search(climbs=2)),
    "shell_hypotheses=0": (1.0, _search(shell_hypotheses=0)),
    "sweep_rotations=0": (1.0, _search(sweep_rotations=0)),
    "coarse_placements=8": (1.0, _search(coarse_placements=8)),
    "peak_ascent=False": (1.0, _search(peak_ascent=False)),
    "turns=0": (1.0, _search(turns=0)),
}

#: The kinds of problem the table reports, and the bench's groups each holds.
KINDS = {
    "views": ("full", "partial", "occluded"),
    "scenes": ("cluttered", "crop_in_scene", "wide"),
    "scan pairs": ("turntable_45", "turntable_90", "turntable_135", "dragon_unoriented",
                   "dragon_24", "dragon_48", "dragon_72", "dragon_96", "dragon_120"),
    "a model into a scan": ("dragon_model",),
    "real YCB-Video": ("ycbv_crop", "ycbv_frame"),
}


def kind_of(group: str) -> str:
    """The kind of problem (a key of :data:`KINDS`) the bench's ``group`` belongs to."""
    return next((k for k, groups in KINDS.items() if group in groups), "other")


def call(task: speed.Task, setting: Setting) -> dict:
    """The global call on ``task`` with ``setting``: its seconds, errors and success."""
    factor, kwargs = setting
    start = time.perf_counter()
    result = o3d_spectral.registration_spectral_global(task.source, task.target,
                                                       factor * task.voxel, **kwargs)
    seconds = time.perf_counter() - start
    rotation, translation, success = task.score(np.asarray(result.transformation))
    return {"seconds": seconds, "rotation_error_deg": rotation,
            "translation_error_m": translation, "success": bool(success)}


def summarise(rows: list[dict], settings: list[str]) -> list[dict]:
    """One line per setting and kind of problem (and one over all kinds): the median time
    ratio to the defaults, the calls right, lost and won, the right calls' median
    rotation error."""
    base = {(r["group"], r["instance"]): r for r in rows if r["setting"] == "defaults"}
    lines = []
    for setting in settings:
        mine = [r for r in rows if r["setting"] == setting]
        for kind in [*dict.fromkeys(kind_of(r["group"]) for r in mine), "all"]:
            picked = [r for r in mine if kind in ("all", kind_of(r["group"]))]
            pairs = [(r, base[r["group"], r["instance"]]) for r in picked]
            right = [r for r in picked if r["success"]]
            lines.append({
                "setting": setting, "kind": kind, "calls": len(picked),
                "time_ratio_median": float(np.median([r["seconds"] / b["seconds"]
                                                      for r, b in pairs])),
                "time_ratio_total": float(sum(r["seconds"] for r, _ in pairs)
                                          / sum(b["seconds"] for _, b in pairs)),
                "right": len(right),
                "lost": sum(b["success"] and not r["success"] for r, b in pairs),
                "won": sum(r["success"] and not b["success"] for r, b in pairs),
                "rotation_error_median_deg": float(np.median(
                    [r["rotation_error_deg"] for r in right])) if right else float("nan"),
            })
    return lines


def markdown(summary: list[dict]) -> str:
    lines = ["| setting | problems | calls | time / defaults (median) | time / defaults "
             "(total) | right | lost | won | median rotation error of the right, deg |",
             "|" + " --- |" * 9]
    for s in summary:
        lines.append(f"| {s['setting']} | {s['kind']} | {s['calls']} "
                     f"| {s['time_ratio_median']:.2f} | {s['time_ratio_total']:.2f} "
                     f"| {s['right']} | {s['lost']} "
                     f"| {s['won']} | {s['rotation_error_median_deg']:.2f} |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    speed.add_task_arguments(parser, limit=6, rotations=1)
    parser.add_argument("--out", type=Path, default=Path("out/bench_settings"))
    parser.add_argument("--settings", nargs="+", choices=list(SETTINGS), default=list(SETTINGS))
    parser.add_argument("--from-rows", type=Path,
                        help="summarise a stored rows.csv again instead of running")
    args = parser.parse_args()
    if args.from_rows is not None:
        rows = read_rows(args.from_rows)
        report(rows, list(dict.fromkeys(r["setting"] for r in rows)), args.out)
        return
    settings = ["defaults", *(s for s in args.settings if s != "defaults")]
    tasks = speed.chosen_tasks(parser, args, speed.chosen_groups(args))
    rows: list[dict] = []
    for task in speed.tqdm(tasks, desc="bench_settings", unit="inst"):
        call(task, SETTINGS["defaults"])  # untimed: FFT plans, caches, compiled kernels
        for setting in settings:
            rows.append({"group": task.group, "instance": task.name, "setting": setting,
                         **call(task, SETTINGS[setting])})
    report(rows, settings, args.out)


def report(rows: list[dict], settings: list[str], out: Path) -> None:
    """Write ``rows`` and their summary to ``out`` and print the summary's table."""
    out.mkdir(parents=True, exist_ok=True)
    write_rows(out / "rows.csv", rows)
    summary = summarise(rows, settings)
    write_rows(out / "summary.csv", summary)
    print(markdown(summary))
    print(f"wrote {out / 'rows.csv'}, summary.csv")


def read_rows(path: Path) -> list[dict]:
    """The rows of a stored ``rows.csv``, their numbers and success read back."""
    with open(path, newline="") as handle:
        return [{**r, "seconds": float(r["seconds"]),
                 "rotation_error_deg": float(r["rotation_error_deg"]),
                 "translation_error_m": float(r["translation_error_m"]),
                 "success": r["success"] == "True"} for r in csv.DictReader(handle)]


if __name__ == "__main__":
    main()
