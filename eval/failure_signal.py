"""Table: how well each failure signal tells wrong poses from right ones.

Reads the rows ``eval/bench_speed.py`` wrote (``instances.csv``: every group's global
calls with their success, ``fitness``, ``fit`` and whether the may-be-wrong warning fired:
``confidence`` under 0.5)
and, for the warning and for Open3D's ``fitness`` under customary thresholds (0.3, 0.5,
0.7), prints per group and overall: how many poses were wrong, the signal's precision
(the share of flagged poses that were wrong) and recall (the share of wrong poses
flagged). ``eval/voxel_advice.py`` prints the same table for its runs.

Usage: python eval/failure_signal.py out/bench_speed/instances.csv
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

FITNESS_THRESHOLDS = (0.3, 0.5, 0.7)


def rates(rows: list[dict], flagged) -> tuple[int, int, str, str]:
    """(wrong poses, flagged poses, precision, recall) of the signal ``flagged(row)``."""
    wrong = [str(r["success"]) == "False" for r in rows]  # a CSV's text or a bool
    flags = [flagged(r) for r in rows]
    hits = sum(w and f for w, f in zip(wrong, flags, strict=True))
    precision = f"{hits / sum(flags):.0%}" if sum(flags) else "-"
    recall = f"{hits / sum(wrong):.0%}" if sum(wrong) else "-"
    return sum(wrong), sum(flags), precision, recall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("instances", type=Path)
    args = parser.parse_args()
    with open(args.instances, newline="") as handle:
        rows = [r for r in csv.DictReader(handle) if r["method"] == "spectral_global"]
    signals = {"may-be-wrong warning": lambda r: r["may_be_wrong_warning"] == "True"}
    for threshold in FITNESS_THRESHOLDS:
        signals[f"fitness < {threshold}"] = (
            lambda r, t=threshold: float(r["fitness"]) < t)
    groups = list(dict.fromkeys(r["group"] for r in rows)) + ["all"]
    print("| group | n | wrong | signal | flagged | precision | recall |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for group in groups:
        picked = rows if group == "all" else [r for r in rows if r["group"] == group]
        for name, flagged in signals.items():
            wrong, flags, precision, recall = rates(picked, flagged)
            print(f"| {group} | {len(picked)} | {wrong} | {name} | {flags} | {precision} "
                  f"| {recall} |")


if __name__ == "__main__":
    main()
