"""Voxel advice and failure signal: the suggested voxel size against the hand-chosen one,
and how well the may-be-wrong warning and Open3D's ``fitness`` tell wrong poses from right ones.

Every instance is registered by ``o3d_spectral.registration_spectral_global`` (defaults)
twice: at the hand-chosen voxel size (the suites': 8 mm, as ``o3d-spectral eval`` and the
benchmarks run them; the real groups': ``harness.real.VOXEL_SIZES``) and at
``o3d_spectral.suggest_voxel_size(source, target)`` (once when the two agree); with
``--trial`` a third time by ``o3d_spectral.voxel_trial`` (the rule's size and the others of
its ladder until two agree, the pose they agree on kept; its time is the whole trial's).
Each row's ``tried`` lists the sizes registered and their confidences
(``mm:confidence``, ``;``-separated; one for a single call).

Groups: the suites (``--suites DIR`` holding ``full``, ``partial``, ``occluded``,
``cluttered``), instances ``--start`` to ``--start + --limit``; the real groups
(``harness.real``), every case from ``--rotations`` seeded random rotations of its source.
Success: symmetry-aware rotation error under 5 degrees and translation error at the
source's centroid under 1 cm (``harness.metrics.instance_metrics``, ``real.case_errors``).

Tables printed (Markdown), and written with the rows (``rows.csv``) to ``--out``:

1. voxel advice, per group: the hand-chosen size, the suggested sizes (median, range),
   each one's success rate, the difference in points, and the median time of a call
   (one process, every core);
2. failure signal, per group and overall, on the hand-chosen runs and on the suggested
   ones: how many poses were wrong, and for the may-be-wrong warning
   (``o3d_spectral.evidence.diagnostics.may_be_wrong`` of the rows' ``confidence``, the call's own
   rule: each run checks it against the warning logged) and ``fitness`` under
   0.3 and 0.5, how many were flagged, the precision (share of the
   flagged that were wrong) and the recall (share of the wrong that were flagged).

``--table rows.csv`` prints the tables of earlier rows without registering anything.

Usage: python eval/voxel_advice.py --suites SUITES --out out/voxel_advice
       [--start 0] [--limit 48] [--rotations 2] [--groups full dragon_24 ...] [--trial]
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from pathlib import Path

import numpy as np
from failure_signal import rates  # the same precision and recall as its table

from o3d_spectral.evidence.diagnostics import may_be_wrong

CONDITIONS = ("full", "partial", "occluded", "cluttered")
#: The suites' hand-chosen voxel size (metres): the paper's, as the benchmarks run them.
SUITE_VOXEL = 0.008
FITNESS_THRESHOLDS = (0.3, 0.5)
WARNING_TEXT = "may be wrong"  # in the confidence's warning (o3d_spectral.evidence.diagnostics)


def tasks(groups: list[str], suites: Path | None, start: int, limit: int, rotations: int):
    """``(group, name, source, target, hand voxel, score)`` of every instance; ``score``
    maps an estimate (4, 4) to ``(rotation error deg, translation error m, success)``."""
    from o3d_spectral.harness import real
    from o3d_spectral.harness.metrics import instance_score
    from o3d_spectral.synthetic.suite import load_suite

    for group in groups:
        if group in CONDITIONS:
            suite = load_suite(suites / group)
            for index in range(start, min(start + limit, len(suite))):
                instance = suite[index]
                yield (group, f"{group}_{index:03d}", instance.source, instance.target,
                       SUITE_VOXEL, instance_score(instance))
        else:
            for case, _, _, r in real.rotated_cases([group], rotations):
                yield (group, f"{case.name}_r{r}", case.source, case.target,
                       real.VOXEL_SIZES[group], real.case_score(case))


def register(source, target, voxel: float, score) -> dict:
    """One global call at ``voxel``: its errors, success and failure signals."""
    import o3d_spectral

    began = time.perf_counter()
    result = o3d_spectral.registration_spectral_global(source, target, voxel)
    return scored(result, voxel, time.perf_counter() - began, score,
                  [(voxel, result.confidence)])


def by_trial(source, target, score) -> dict:
    """``o3d_spectral.voxel_trial`` (the sizes of its ladder until two agree): the kept
    call's errors, success and signals, its size, the sizes tried and the whole time."""
    import o3d_spectral

    began = time.perf_counter()
    trial = o3d_spectral.voxel_trial(source, target)
    return scored(trial.result, trial.voxel_size, time.perf_counter() - began, score,
                  trial.tried)


def scored(result, voxel: float, seconds: float, score, tried) -> dict:
    """The row of a registration ``result`` at ``voxel`` (metres) that took ``seconds``;
    ``tried``: the sizes registered (metres) and their confidences."""
    rotation, translation, success = score(np.asarray(result.transformation))
    warned = any(WARNING_TEXT in w for w in result.warnings)
    if warned != may_be_wrong(result.confidence):  # the table recomputes it so
        raise AssertionError("the warning disagrees with diagnostics.may_be_wrong")
    return {"voxel_m": voxel, "seconds": seconds, "rotation_error_deg": rotation,
            "translation_error_m": translation, "success": bool(success),
            "fitness": result.fitness, "fit": result.fit, "rival_fit": result.rival_fit,
            "confidence": result.confidence, "confirmed": result.confirmed,
            "warned": warned,
            "tried": ";".join(f"{v * 1e3:.3f}:{c:.4f}" for v, c in tried)}


def run(args: argparse.Namespace, csv_path: Path) -> list[dict]:
    """Both registrations of every instance; each instance's rows are appended to
    ``csv_path`` as they come (an interrupted run keeps them)."""
    import open3d as o3d

    import o3d_spectral

    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    groups = [g for g in args.groups if g not in CONDITIONS or args.suites is not None]
    rows: list[dict] = []
    handle, writer = open(csv_path, "w", newline=""), None
    for group, name, source, target, hand, score in tasks(groups, args.suites, args.start,
                                                         args.limit, args.rotations):
        began = time.perf_counter()
        suggested = o3d_spectral.suggest_voxel_size(source, target)
        advice_s = time.perf_counter() - began
        first = register(source, target, hand, score)
        second = first if np.isclose(suggested, hand, rtol=1e-9, atol=0.0) else register(
            source, target, suggested, score)
        chosen = [("hand", first), ("suggested", second)]
        if args.trial:
            chosen.append(("trial", by_trial(source, target, score)))
        for choice, row in chosen:
            rows.append({"group": group, "instance": name, "choice": choice,
                         "advice_s": advice_s} | row)
            if writer is None:
                writer = csv.DictWriter(handle, fieldnames=list(rows[-1]))
                writer.writeheader()
            writer.writerow(rows[-1])
        handle.flush()
        print(f"{name}: " + ", ".join(
            f"{choice} {row['voxel_m'] * 1e3:.2f} mm {'ok' if row['success'] else 'FAIL'}"
            for choice, row in chosen), file=sys.stderr, flush=True)
    handle.close()
    return rows


def _true(value) -> bool:
    return value is True or str(value) == "True"


def advice_table(rows: list[dict]) -> str:
    """Per group: the hand-chosen size's success; the suggested size's (and, when the run
    has them, the trial's: ``--trial``) success, difference in points and median time."""
    choices = [c for c in ("suggested", "trial") if any(r["choice"] == c for r in rows)]
    head = ["group", "n", "hand mm", "suggested mm: median (range)", "hand success"]
    for choice in choices:
        head += [f"{choice} success", "difference, points"]
    head.append("median s, " + " / ".join(["hand", *choices]))
    lines = ["| " + " | ".join(head) + " |", "|" + " --- |" * len(head)]
    groups = list(dict.fromkeys(r["group"] for r in rows))
    for group in [*groups, "all"]:
        mine = [r for r in rows if group in ("all", r["group"])]
        picked = {c: [r for r in mine if r["choice"] == c] for c in ("hand", *choices)}
        sizes = np.array([float(r["voxel_m"]) for r in picked["suggested"]]) * 1e3
        hand_sizes = sorted({round(float(r["voxel_m"]) * 1e3, 2) for r in picked["hand"]})
        a = 100 * np.mean([_true(r["success"]) for r in picked["hand"]])
        cells = [group, str(len(picked["hand"])), ", ".join(f"{s:g}" for s in hand_sizes),
                 f"{np.median(sizes):.1f} ({sizes.min():.1f}-{sizes.max():.1f})", f"{a:.1f}%"]
        for choice in choices:
            b = 100 * np.mean([_true(r["success"]) for r in picked[choice]])
            cells += [f"{b:.1f}%", f"{b - a:+.1f}"]
        cells.append(" / ".join(f"{np.median([float(r['seconds']) for r in picked[c]]):.2f}"
                                for c in ("hand", *choices)))
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def signal_table(rows: list[dict], choice: str) -> str:
    # the warning as diagnostics.may_be_wrong flags it (the call's own rule, which run()
    # checks against the logged warning)
    signals = {"may-be-wrong warning": lambda r: may_be_wrong(float(r["confidence"]))}
    for t in FITNESS_THRESHOLDS:
        signals[f"fitness < {t}"] = lambda r, t=t: float(r["fitness"]) < t
    names = list(signals)
    head = "| group | n | wrong | " + " | ".join(
        f"{n}: flagged, precision, recall" for n in names) + " |"
    lines = [head, "|" + " --- |" * (3 + len(names))]
    picked = [r for r in rows if r["choice"] == choice]
    groups = list(dict.fromkeys(r["group"] for r in picked))
    for group in [*groups, "all"]:
        mine = [r for r in picked if group in ("all", r["group"])]
        cells = []
        for name in names:
            wrong, flags, precision, recall = rates(mine, signals[name])
            cells.append(f"{flags}, {precision}, {recall}")
        lines.append(f"| {group} | {len(mine)} | {wrong} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def report(rows: list[dict]) -> str:
    return "\n\n".join([
        "Voxel advice (success: symmetry-aware, 5 deg and 1 cm):", advice_table(rows),
        "Failure signal, runs at the hand-chosen voxel size:", signal_table(rows, "hand"),
        "Failure signal, runs at the suggested voxel size:", signal_table(rows, "suggested"),
    ])


def main() -> None:
    from o3d_spectral.harness import real

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--suites", type=Path, help="folder of the four suites")
    parser.add_argument("--out", type=Path, default=Path("out/voxel_advice"))
    parser.add_argument("--start", type=int, default=0, help="first suite instance")
    parser.add_argument("--limit", type=int, default=48, help="suite instances per suite")
    parser.add_argument("--rotations", type=int, default=2, help="rotations per real case")
    parser.add_argument("--trial", action="store_true",
                        help="also register by o3d_spectral.voxel_trial (its ladder of sizes)")
    parser.add_argument("--groups", nargs="+", choices=(*CONDITIONS, *real.GROUPS),
                        default=[*CONDITIONS, *real.GROUPS])
    parser.add_argument("--table", type=Path, metavar="ROWS_CSV",
                        help="print the tables of these rows and stop")
    args = parser.parse_args()
    if args.table is not None:
        with open(args.table, newline="") as handle:
            print(report(list(csv.DictReader(handle))))
        return
    args.out.mkdir(parents=True, exist_ok=True)
    rows = run(args, args.out / "rows.csv")
    if not rows:
        parser.error("no instances: give --suites or real groups")
    text = report(rows)
    (args.out / "tables.md").write_text(text + "\n")
    print(text)


if __name__ == "__main__":
    main()
