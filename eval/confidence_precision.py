"""How far the global spectral call's ``confidence`` can be trusted: precision and
coverage at a few thresholds.

For each threshold ``t``: *coverage* is the share of registrations whose confidence is at
least ``t``, *precision* the share of those that succeeded. Reads the rows of an
``o3d-spectral eval`` run (method ``spectral_global``, its ``confidence`` and ``success``
columns) and/or the ``rows.csv`` of ``eval/bench_real.py``, and prints one Markdown table
per source, by suite or real group.

Usage: python eval/confidence_precision.py [--run RUN_DIR] [--real out/bench_real/rows.csv]
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import numpy as np

#: Thresholds of the calibrated confidence (a probability; the warning fires under 0.5).
THRESHOLDS = (0.0, 0.5, 0.7, 0.9, 0.95)


def table(groups: dict[str, tuple[np.ndarray, np.ndarray]]) -> str:
    """Markdown: one row per group, precision (coverage) per threshold."""
    head = "| group | n | " + " | ".join(f"conf >= {t:g}" for t in THRESHOLDS) + " |"
    lines = [head, "|" + " --- |" * (len(THRESHOLDS) + 2)]
    for name, (confidence, success) in groups.items():
        cells = []
        for t in THRESHOLDS:
            kept = confidence >= t
            precision = f"{100 * success[kept].mean():.0f}%" if kept.any() else "-"
            cells.append(f"{precision} ({100 * kept.mean():.0f}%)")
        lines.append(f"| {name} | {len(confidence)} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _pooled(groups: dict[str, tuple[np.ndarray, np.ndarray]]) -> dict:
    confidence = np.concatenate([c for c, _ in groups.values()])
    success = np.concatenate([s for _, s in groups.values()])
    return groups | {"all": (confidence, success)}


def from_run(run: Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    from o3d_spectral.harness import load_results

    frame = load_results(run)
    frame = frame[(frame["method"] == "spectral_global") & frame["confidence"].notna()]
    return {str(suite): (part["confidence"].to_numpy(float), part["success"].to_numpy(bool))
            for suite, part in frame.groupby("suite", sort=False)}


def from_real(path: Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    with open(path, newline="") as handle:
        rows = [r for r in csv.DictReader(handle) if r["method"] == "spectral_global"]
    groups: dict[str, list] = {}
    for r in rows:
        groups.setdefault(f"{r['group']} ({r['mode']})", []).append(
            (float(r["confidence"]), r["success"] == "True"))
    return {k: (np.array([c for c, _ in v]), np.array([s for _, s in v]))
            for k, v in groups.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--run", type=Path, help="an eval run folder")
    parser.add_argument("--real", type=Path, help="rows.csv of eval/bench_real.py")
    args = parser.parse_args()
    if args.run is None and args.real is None:
        parser.error("give --run and/or --real")
    print("precision (coverage): share of successes among results with confidence >= t "
          "(share of results kept)\n")
    if args.run is not None:
        print(table(_pooled(from_run(args.run))) + "\n")
    if args.real is not None:
        print(table(_pooled(from_real(args.real))))


if __name__ == "__main__":
    main()
