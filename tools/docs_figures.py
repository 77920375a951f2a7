"""Write the measured figures of README.md and docs/ from the stored bench outputs.

Every generated block of the docs sits between ``<!-- figures:NAME -->`` and
``<!-- /figures -->``; this script rewrites each from the files in ``docs/data/``.
``docs/data/sources.json`` names each stored output, the command that wrote it and the
commit it was measured at; every block states that commit and command, so a figure in the
docs always has a stored output behind it. ``tests/test_docs.py`` renders the blocks again
and fails when a doc differs (a hand edit, or a stored output changed without the docs).

    python tools/docs_figures.py           # rewrite the blocks in place
    python tools/docs_figures.py --check   # exit 1 and show the difference if one differs

To update a figure: run the command its source names, copy the output it wrote into
``docs/data/`` under the same name, set the source's ``commit`` in ``sources.json``, and
run this script.
"""

from __future__ import annotations

import argparse
import csv
import difflib
import json
import re
import sys
from collections.abc import Callable
from pathlib import Path
from statistics import median

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "docs" / "data"
BLOCK = re.compile(r"(<!-- figures:([\w-]+) -->\n)(.*?)(<!-- /figures -->)", re.DOTALL)

#: The suites as ``o3d-spectral report`` names them, in the docs' order, and their short names.
SUITES = {"C-1 (full)": "full", "C-2 (partial)": "partial", "occluded": "occluded",
          "C-3 (cluttered)": "cluttered"}
#: Methods of the all-methods table, in its order.
METHODS = ("spectral_global", "spectral_global_unrefined", "spectral_global_whole_egi",
           "fpfh_ransac", "fpfh_ransac_tuned", "fgr", "kiss_matcher", "small_gicp",
           "icp_point_to_plane", "icp_point_to_point", "spectral", "spectral_paper")


def sources() -> dict[str, dict]:
    """The stored outputs by name: ``file``, ``command``, ``commit`` (``sources.json``)."""
    return json.loads((DATA / "sources.json").read_text())


def read_csv(name: str) -> list[dict[str, str]]:
    """Rows of the stored output ``name`` (a CSV file in ``docs/data/``)."""
    with open(DATA / sources()[name]["file"], newline="") as f:
        return list(csv.DictReader(f))


def summary(name: str) -> dict[tuple[str, str], dict[str, str]]:
    """An ``o3d-spectral report`` ``summary.csv`` keyed by (short suite name, method)."""
    return {(SUITES[r["suite"]], r["method"]): r for r in read_csv(name)}


def provenance(*names: str) -> str:
    """One line naming each source's commit, command and stored file."""
    parts = []
    for name in names:
        s = sources()[name]
        parts.append(f"commit {s['commit']}: `{s['command']}` (`docs/data/{s['file']}`)")
    return "Measured at " + "; ".join(parts) + "."


def table(header: list[str], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + " --- |" * len(header)]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines)


def pct(row: dict[str, str]) -> str:
    """The row's success rate in percent, one decimal ("99.6")."""
    return f"{100 * float(row['success (%)']):.1f}"


def successes(row: dict[str, str]) -> int:
    return round(float(row["success (%)"]) * int(row["n"]))


def c1_local() -> dict[str, str]:
    """The ``all`` line and the headline of ``eval/c1_local.py``'s printed table."""
    text = (DATA / sources()["c1_local"]["file"]).read_text()
    head = re.search(r"(\d+)/(\d+) = ([\d.]+)% within 1 deg and 2 mm", text)
    columns = ("ok", "rot_med", "rot_p95", "rot_max", "t_med", "t_max", "iter", "time")
    values = re.search(r"^all\s+(.*)$", text, re.MULTILINE).group(1).split()
    if head is None or len(values) != len(columns):
        raise ValueError("docs/data: c1_local output not in eval/c1_local.py's format")
    return dict(zip(columns, values, strict=True)) | {
        "good": head.group(1), "cases": head.group(2), "share": head.group(3)}


#: ``eval/bench_real.py``'s groups, in the docs' order, and how the docs name them.
REAL_GROUPS = {"dragon_24": "dragon, scans 24 deg apart", "dragon_48": "dragon, 48 deg",
               "dragon_72": "dragon, 72 deg", "dragon_96": "dragon, 96 deg",
               "dragon_120": "dragon, 120 deg",
               "ycbv_crop": "YCB-Video object model into its crop",
               "ycbv_frame": "YCB-Video model into the whole frame"}
#: ``eval/bench_real.py``'s normal modes, in the docs' order.
NORMAL_MODES = ("oriented", "unoriented", "none")


def real_success(method: str) -> dict[str, list[int]]:
    """Per real group, ``method``'s success in percent (rounded) in each normal mode."""
    rows = {(r["group"], r["mode"]): r for r in read_csv("real_scans")}
    return {g: [round(100 * float(rows[g, m][f"{method}_success"])) for m in NORMAL_MODES]
            for g in REAL_GROUPS}


def span(values: list[float], digits: int = 0, scale: float = 1.0) -> str:
    """``"96-100"`` for values from 96 to 100 (times ``scale``, ``digits`` decimals), one
    figure when all agree."""
    low, high = (f"{scale * min(values):.{digits}f}", f"{scale * max(values):.{digits}f}")
    return low if low == high else f"{low}-{high}"


# --- the blocks -------------------------------------------------------------------------


def readme() -> str:
    current, run = summary("suites_spectral_global"), summary("suites_all_methods")
    spectral, fpfh = real_success("spectral_global"), real_success("fpfh_ransac")
    c1 = c1_local()
    n = current["full", "spectral_global"]["n"]
    dragons = ("dragon_24", "dragon_48", "dragon_72", "dragon_96", "dragon_120")
    ycbv = ("ycbv_crop", "ycbv_frame")
    rows = [
        [f"{n} full models / partial views / occluded views / cluttered scenes",
         " / ".join(pct(current[s, "spectral_global"]) for s in SUITES.values()) + "%",
         " / ".join(pct(run[s, "fpfh_ransac"]) for s in SUITES.values()) + "%"],
        ["dragon laser scans 24 / 48 / 72 / 96 / 120 degrees apart, any rotation",
         " / ".join(span(spectral[g]) for g in dragons) + "%",
         " / ".join(span(fpfh[g]) for g in dragons) + "%"],
        ["YCB-Video model into its RGB-D crop / the whole frame",
         " / ".join(span(spectral[g]) for g in ycbv) + "%",
         " / ".join(span(fpfh[g]) for g in ycbv) + "%"],
        ["paper's C-1 (full model, rotations up to 45 deg; the law alone)",
         f"{c1['share'].removesuffix('.0')}% within 1 deg, 2 mm", ""],
    ]
    commit = sources()["suites_spectral_global"]["commit"]
    if not sources()["real_scans"]["commit"] == sources()["c1_local"]["commit"] == commit:
        raise ValueError("the README's rows are measured at one commit: update them together")
    return "\n".join([
        table(["success (5 deg and 1 cm)", "`registration_spectral_global`", "FPFH-RANSAC"],
              rows),
        "",
        f"Measured at commit {commit}, FPFH-RANSAC on the suites at "
        f"{sources()['suites_all_methods']['commit_other']}; the real scans' ranges are over "
        f"3 ways of giving normals (stored in `docs/data/`).",
    ])


def real_scans() -> str:
    spectral, fpfh = real_success("spectral_global"), real_success("fpfh_ransac")
    n = {r["group"]: r["n"] for r in read_csv("real_scans")}
    rows = [[label, n[g], " / ".join(map(str, spectral[g])) + "%",
             " / ".join(map(str, fpfh[g])) + "%"] for g, label in REAL_GROUPS.items()]
    return "\n".join([
        table(["group", "n per mode", "spectral success", "FPFH-RANSAC success"], rows),
        "",
        provenance("real_scans") + " Times of this run are not quoted (the machine was shared).",
    ])


def bop() -> str:
    names = {"bop_ycbv_test_crop": "model into its crop",
             "bop_ycbv_test_frame": "model into the whole frame"}
    rows = []
    for r in read_csv("bop_ycbv"):
        n = int(r["n"])
        rows.append([names[r["suite"]], r["method"], str(n),
                     *(f"{float(r[k]):.3f}" for k in ("AR", "AR VSD", "AR MSSD", "AR MSPD")),
                     f"{round(float(r['success (%)']) * n)}/{n}"])
    return "\n".join([
        table(["instances", "method", "n", "AR", "AR VSD", "AR MSSD", "AR MSPD",
               "success (5 deg, 1 cm)"], rows),
        "",
        provenance("bop_ycbv"),
    ])


def pairs() -> str:
    rows = [[r["method"], r["pairs"], f"{100 * float(r['recall RE/TE (%)']):.1f}%",
             f"{100 * float(r['recall RMSE (%)']):.1f}%",
             f"{float(r['RE (deg)']):.2f}", f"{float(r['TE (cm)']):.2f}"]
            for r in read_csv("dragon_3dmatch")]
    return "\n".join([
        table(["method", "pairs", "recall RE < 15 deg, TE < 30 cm", "recall RMSE <= 20 cm",
               "RE (deg)", "TE (cm)"], rows),
        "",
        provenance("dragon_3dmatch"),
    ])


def suites_current() -> str:
    current, run = summary("suites_spectral_global"), summary("suites_all_methods")
    rows = []
    for suite in SUITES.values():
        r, f = current[suite, "spectral_global"], run[suite, "fpfh_ransac"]
        failures = int(r["n"]) - successes(r)
        rows.append([suite, r["n"], f"{pct(r)}%", f"{float(r['rotation error (deg)']):.2f}",
                     f"{float(r['translation error (mm)']):.2f}", str(failures),
                     r["indistinguishable"], f"{pct(f)}%"])
    return "\n".join([
        table(["suite", "n", "success", "median rotation error (deg)",
               "median translation error (mm)", "failures", "indistinguishable",
               "FPFH-RANSAC"], rows),
        "",
        provenance("suites_spectral_global"),
        f"FPFH-RANSAC: the all-methods run below (commit "
        f"{sources()['suites_all_methods']['commit_other']}). Median errors are over the "
        f"successes; this run's times are not quoted (the machine was shared).",
    ])


def suites_all() -> str:
    run = summary("suites_all_methods")
    rows = []
    for method in METHODS:
        cells = [run[s, method] for s in SUITES.values()]
        n = {c["n"] for c in cells}
        name = f"`{method}`" + ("" if n == {"240"} else f" ({'/'.join(sorted(n))} per suite)")
        rows.append([name, *(f"{pct(c)}%" for c in cells),
                     " / ".join(f"{float(c['median time (s)']):.3f}" for c in cells)])
    s = sources()["suites_all_methods"]
    return "\n".join([
        table(["method", *SUITES.values(), "median s (full / partial / occluded / cluttered)"],
              rows),
        "",
        f"Measured in one run folder: the spectral methods at commit {s['commit']}, the "
        f"others at {s['commit_other']}: `{s['command']}` (`docs/data/{s['file']}`).",
    ])


def c1() -> str:
    c = c1_local()
    return (
        f"{c['good']} of {c['cases']} ({c['share']}%) within 1 deg and 2 mm; rotation error "
        f"median {c['rot_med']} deg, p95 {c['rot_p95']} deg; translation error median "
        f"{c['t_med']} mm, max {c['t_max']} mm. {provenance('c1_local')}"
    )


def method_failures() -> str:
    current = summary("suites_spectral_global")
    share = {s: 100 - 100 * float(current[s, "spectral_global"]["success (%)"])
             for s in SUITES.values()}
    parts = {s: (current[s, "spectral_global"]["indistinguishable"],
                 int(current[s, "spectral_global"]["n"]) - successes(current[s, "spectral_global"]))
             for s in ("occluded", "cluttered")}
    commit = sources()["suites_spectral_global"]["commit"]
    return (
        f"- Like FPFH-RANSAC it fails on a share of single views ({share['partial']:.0f}% of\n"
        f"  partial views, {share['occluded']:.0f}% of occluded views, "
        f"{share['cluttered']:.0f}% of cluttered scenes;\n"
        f"  the 960-instance suites at commit {commit}); of those failures "
        f"{parts['occluded'][0]} of {parts['occluded'][1]}\n"
        f"  occluded and {parts['cluttered'][0]} of {parts['cluttered'][1]} cluttered are "
        f"poses that fit the observed points as well as\n"
        f"  the ground truth does, which the view cannot settle."
    )


def confidence() -> str:
    """The calibrated confidence on the held-back calls: pooled, then per group."""
    pooled = {(r["confidence"], r["part"]): r for r in read_csv("calibrate_confidence_summary")}
    held = pooled["library", "held back"]

    def cell(value: str, digits: int, percent: bool = False) -> str:
        if value in ("", "nan"):
            return "-"
        return f"{100 * float(value):.0f}%" if percent else f"{float(value):.{digits}f}"

    rows = [[r["group"], r["n"], r["wrong"], cell(r["auroc"], 2),
             f"{r['warned_wrong']} / {r['wrong']}", r["warned_right"], cell(r["brier"], 3)]
            for r in read_csv("calibrate_confidence_groups")]
    return "\n".join([
        f"Held back: {held['n']} calls, {held['wrong']} wrong: AUROC "
        f"{float(held['auroc']):.3f}; the warning (confidence < 0.5): precision "
        f"{cell(held['precision'], 0, True)}, recall {cell(held['recall'], 0, True)}; "
        f"Brier score {float(held['brier']):.3f}.",
        "",
        table(["group (held back)", "n", "wrong", "AUROC", "wrong warned", "right warned",
               "Brier"], rows),
        "",
        provenance("calibrate_confidence_summary") + " Per group: "
        "`docs/data/calibrate_confidence_groups.csv`; every call: "
        "`docs/data/calibrate_confidence_rows.csv`.",
    ])


def confidence_misses() -> str:
    """The wrong poses held back that the warning misses, by group."""
    pooled = {(r["confidence"], r["part"]): r for r in read_csv("calibrate_confidence_summary")}
    held = pooled["library", "held back"]
    missed = [(r["group"], int(r["wrong"]) - int(r["warned_wrong"]))
              for r in read_csv("calibrate_confidence_groups")]
    by_group = ", ".join(f"{group} {n}" for group, n in missed if n)
    return (
        f"The warning's recall is {100 * float(held['recall']):.0f}%: it misses "
        f"{int(held['wrong']) - int(held['warned_wrong'])} of the {held['wrong']} wrong poses "
        f"held back ({by_group}). " + provenance("calibrate_confidence_groups")
    )


def confidence_held_out() -> str:
    """The confidence refitted with each object, then each group, held back in turn: the
    pooled held-back figures, the folds' worst AUROC, and the calls' silent wrong poses
    and warned right ones."""
    def share(value: str) -> str:
        return "-" if value in ("", "nan") else f"{100 * float(value):.0f}%"

    rows = []
    for split in ("object", "group"):
        pooled = {r["confidence"]: r for r in read_csv(f"calibrate_confidence_{split}_summary")}
        folds = [r for r in read_csv(f"calibrate_confidence_{split}_folds")
                 if r["auroc"] not in ("", "nan")]
        worst = min(folds, key=lambda r: float(r["auroc"]))
        refit = pooled["refit"]
        rows.append([f"each {split} held back", refit["n"], refit["wrong"],
                     f"{float(refit['auroc']):.3f}",
                     f"{float(worst['auroc']):.2f} ({worst['fold']})",
                     share(refit["precision"]), share(refit["recall"]),
                     f"{float(refit['brier']):.3f}"])
    silent = read_csv("calibrate_confidence_silent")[0]
    return "\n".join([
        table(["refitted with", "n", "wrong", "AUROC", "worst fold's AUROC",
               "warning precision", "recall", "Brier"], rows),
        "",
        f"The library's own calls: {silent['silent_wrong']} of {silent['wrong']} wrong poses "
        f"came back with confidence 0.5 or more and no warning; {silent['right_warned']} of "
        f"{silent['right']} right poses carried a warning, {silent['right_ambiguous']} of "
        f"them that another pose fits as well; in {silent['right_ambiguous_other_wrong']} of "
        "those the other pose (`result.ambiguous_transformation`) is wrong: the data allow "
        "a wrong answer.",
        "",
        provenance("calibrate_confidence_object_summary", "calibrate_confidence_group_summary",
                   "calibrate_confidence_silent") + " Per fold: "
        "`docs/data/calibrate_confidence_object_folds.csv`, "
        "`docs/data/calibrate_confidence_group_folds.csv`.",
    ])


#: ``eval/bench_density.py``'s methods, in the docs' order, and how the docs name them.
DENSITY_METHODS = {"spectral_global": "spectral", "fpfh_ransac_lean": "lean FPFH-RANSAC"}
#: The stages of ``registration_spectral_global`` in ``eval/bench_density.py``'s summary.
DENSITY_STAGES = ("prepare", "candidates", "confirm", "sweep", "climbs", "ascent", "polish")


def density() -> str:
    """Time against raw density at a fixed voxel: both methods, then spectral's stages."""
    rows = {(int(r["multiplier"]), r["method"]): r for r in read_csv("density")}
    multipliers = sorted({m for m, _ in rows})
    lines = []
    for m in multipliers:
        first = rows[m, "spectral_global"]
        cells = [f"{m}x", first["n"],
                 f"{float(first['median_source_points']):.0f} / "
                 f"{float(first['median_target_points']):.0f}"]
        for method in DENSITY_METHODS:
            r = rows[m, method]
            cells += [f"{float(r['median_s']):.3f}", f"{float(r['median_ratio_to_1x']):.2f}",
                      f"{100 * float(r['success']):.0f}%"]
        lines.append(cells)
    header = ["points", "n", "median points (source / target)"]
    for name in DENSITY_METHODS.values():
        header += [f"{name} median s", f"{name} ratio to 1x", f"{name} success"]
    def cells(row: dict[str, str], key: str, digits: int) -> list[str]:
        values = [float(row[f"{s}_median_{key}"]) for s in DENSITY_STAGES]
        return ["-" if v != v else f"{v:.{digits}f}" for v in values]  # v != v: NaN

    stages = [[f"{m}x", *cells(rows[m, "spectral_global"], "s", 3)] for m in multipliers]
    low, high = multipliers[0], multipliers[-1]
    last = rows[high, "spectral_global"]
    stages += [[f"{high}x vs {low}x: median s added", *cells(last, "added_s", 3)],
               [f"{high}x vs {low}x: median ratio", *cells(last, "ratio_to_1x", 2)]]
    return "\n".join([
        table(header, lines),
        "",
        "Spectral's stages (`result.stage_times`; a skipped stage counts 0 s): median "
        f"seconds over the instances; then, over the instances, the median of the seconds "
        f"each stage added from {low}x to {high}x and of its ratio (- where it ran at no "
        f"instance at {low}x):",
        "",
        table(["points", *DENSITY_STAGES], stages),
        "",
        provenance("density") + " One thread per call, 2 cores shared with other jobs: "
        "times are indicative; every row in `docs/data/density.csv`.",
    ])


def density_notes() -> str:
    """The density run read by method: how time rises from the fewest points to the most,
    and which models fail at which densities."""
    rows = {(int(r["multiplier"]), r["method"]): r for r in read_csv("density")}
    low, high = min(m for m, _ in rows), max(m for m, _ in rows)
    rise = {m: (float(rows[high, m]["median_ratio_to_1x"]), float(rows[high, m]["max_ratio_to_1x"]))
            for m in DENSITY_METHODS}
    faster = float(rows[low, "spectral_global"]["median_s"]) / float(
        rows[low, "fpfh_ransac_lean"]["median_s"])
    failed = [r for r in read_csv("density_rows") if r["success"] != "True"]
    fails = []
    for model in dict.fromkeys(r["model"] for r in failed):
        mine = [r for r in failed if r["model"] == model]
        methods = " and ".join(DENSITY_METHODS[m] for m in dict.fromkeys(r["method"] for r in mine))
        where = sorted({int(r["multiplier"]) for r in mine})
        at = "every density" if len(where) == len({m for m, _ in rows}) else \
            " and ".join(f"{m}x" for m in where)
        fails.append(f"the {model.replace('_', ' ')} fails for {methods} at {at} "
                     f"({span(_column(mine, 'rotation_error_deg'))} degrees off)")
    (s_median, s_max), (f_median, f_max) = rise.values()
    return (
        f"From {low}x to {high}x the spectral call's time rises by a median {s_median:.2f}x "
        f"(the largest {s_max:.2f}x), against {f_median:.2f}x (the largest {f_max:.2f}x) for "
        f"the lean FPFH-RANSAC, whose median time at {low}x is {faster:.1f} times smaller. "
        f"Success does not follow the density: {'; '.join(fails) or 'no model fails'}. "
        + provenance("density_rows")
    )


def speed(name: str = "speed") -> str:
    """The speed bench (the stored output ``name``): each group's median times, ratios
    against the lean FPFH-RANSAC (and the tutorial's pipeline), success and early stops."""
    rows = read_csv(name)
    header = ["group", "n", "spectral median s", "lean FPFH median s", "tutorial FPFH median s",
              "ratio median", "ratio p90", "ratio median (tutorial)", "spectral success",
              "lean FPFH success", "tutorial FPFH success", "early stops", "wrong early stops"]
    lines = [[r["group"], r["n"], *(f"{float(r[k]):.3f}" for k in (
        "spectral_global_median_s", "fpfh_ransac_lean_median_s", "fpfh_ransac_median_s")),
        *(f"{float(r[k]):.2f}" for k in ("ratio_median", "ratio_p90", "ratio_median_tutorial")),
        *(f"{100 * float(r[k]):.0f}%" for k in (
            "spectral_global_success", "fpfh_ransac_lean_success", "fpfh_ransac_success",
            "early_stops")), r["early_stops_wrong"]] for r in rows]
    return "\n".join([
        table(header, lines),
        "",
        provenance(name) + " One thread per call, each instance's median of three "
        "calls with the methods in turn; ratio = spectral / lean FPFH-RANSAC (its ICP on "
        "both clouds thinned to half the voxel); early stops: spectral calls confirmed "
        "before the climbs, and how many of them were wrong. Read a ratio to within about "
        "20%: the virtual machine drifts between runs.",
    ])


def speed_change() -> str:
    """The speed bench at two commits run one after the other, one thread: each group's
    median ratio to the lean FPFH-RANSAC and both methods' median seconds, before and
    now."""
    return _change("speed_before", "speed_loop", "one thread")


def cores_change() -> str:
    """:func:`speed_change` for the bench on every core."""
    return _change("speed_all_cores_before", "speed_all_cores_loop", "every core")


def _change(before_source: str, now_source: str, threads: str) -> str:
    """Each group's median ratio and both methods' median seconds in two runs of the speed
    bench (sources ``before_source`` and ``now_source``), before and now."""
    now = {r["group"]: r for r in read_csv(now_source)}
    lines = []
    for before in read_csv(before_source):
        after = now[before["group"]]
        pair = (before, after)
        lines.append([before["group"], *(f"{float(r['ratio_median']):.2f}" for r in pair),
                      *(f"{float(r[k]):.3f}" for k in ("spectral_global_median_s",
                                                        "fpfh_ransac_lean_median_s")
                        for r in pair)])
    b, a = sources()[before_source]["commit"], sources()[now_source]["commit"]
    return "\n".join([
        table(["group", f"ratio median, {b}", f"ratio median, {a}", f"spectral s, {b}",
               f"spectral s, {a}", f"lean FPFH s, {b}", f"lean FPFH s, {a}"], lines),
        "",
        provenance(before_source, now_source) + f" The two runs in the same session on the "
        f"same instances, {threads}; both methods' times drift together between runs by "
        "up to a quarter on this virtual machine.",
    ])


def speed_stages() -> str:
    """Where the spectral call's time goes, per group: each stage's median seconds and its
    multiple of the lean FPFH-RANSAC's whole call, from ``eval/bench_stages.py``'s rows."""
    rows = read_csv("speed_stages")
    named = ("group", "instance", "confirmed", "total", "lean FPFH-RANSAC")
    stages = [s for s in rows[0] if s not in named and any(float(r[s]) > 0 for r in rows)]
    lines, beyond = [], []
    for group in dict.fromkeys(r["group"] for r in rows):
        mine = [r for r in rows if r["group"] == group]
        lean = median([float(r["lean FPFH-RANSAC"]) for r in mine])
        seconds = {s: median([float(r[s]) for r in mine]) for s in stages}
        over = [s for s in stages if seconds[s] > lean]
        if over:
            beyond.append(group)
        lines.append([group, str(len(mine)), f"{lean:.3f}",
                      f"{median([float(r['total']) for r in mine]):.3f}",
                      *("-" if seconds[s] == 0 else f"{seconds[s]:.3f} ({seconds[s] / lean:.2f}x)"
                        for s in stages)])
    return "\n".join([
        table(["group", "n", "lean FPFH s", "spectral s", *stages], lines),
        "",
        f"Each stage's median seconds over the group's calls (- where the median call skipped "
        f"it) and, in "
        f"brackets, that as a multiple of the lean FPFH-RANSAC's median call. In "
        f"{len(beyond)} of {len(lines)} groups at least one stage alone takes longer than "
        f"the lean call whole. " + provenance("speed_stages") + " One call of each method per "
        "instance, one thread.",
    ])


def settings() -> str:
    """What each setting of the global call buys in time and costs in success, per kind of
    problem, against the defaults on the same instances (``eval/bench_settings.py``)."""
    rows = read_csv("settings")
    kinds = list(dict.fromkeys(r["kind"] for r in rows if r["kind"] != "all"))
    by = {(r["setting"], r["kind"]): r for r in rows}
    lines = []
    for setting in dict.fromkeys(r["setting"] for r in rows):
        every = by[setting, "all"]
        lines.append([f"`{setting}`", *(f"{float(by[setting, k]['time_ratio_total']):.2f}"
                                        for k in kinds),
                      f"{every['right']} of {every['calls']}", every["lost"], every["won"],
                      f"{float(every['rotation_error_median_deg']):.2f}"])
    return "\n".join([
        table(["setting", *(f"time / defaults, {k}" for k in kinds), "right", "lost", "won",
               "median rotation error of the right, deg"], lines),
        "",
        provenance("settings") + " Time: the total seconds of a kind's calls over their "
        "total at the defaults (a batch's saving; each call's own ratio in "
        "`docs/data/settings_rows.csv`), one thread, each call timed once (read a ratio "
        "to within about 10%); right: 5 degrees and 1 cm; lost and won: against the "
        "defaults.",
    ])


def cores() -> str:
    """What every core gains over one thread, per group, for both methods: the speed
    bench's one-thread medians over its ``--all-cores`` medians."""
    one = {r["group"]: r for r in read_csv("speed")}
    lines = []
    for r in read_csv("speed_all_cores"):
        single = one[r["group"]]
        gains = [float(single[k]) / float(r[k]) for k in (
            "spectral_global_median_s", "fpfh_ransac_lean_median_s")]
        lines.append([r["group"], r["n"], f"{float(r['spectral_global_median_s']):.3f}",
                      f"{float(r['fpfh_ransac_lean_median_s']):.3f}",
                      *(f"{g:.2f}x" for g in gains), f"{float(r['ratio_median']):.2f}"])
    return "\n".join([
        table(["group", "n", "spectral median s, all cores", "lean FPFH median s, all cores",
               "spectral gain over one thread", "lean FPFH gain over one thread",
               "ratio median, all cores"], lines),
        "",
        provenance("speed", "speed_all_cores") + " Gain: the one-thread run's median over "
        "the all-cores run's, per method; both at their defaults on every core of this "
        "2-core machine.",
    ])


def voxel_trial() -> str:
    """The voxel size by trial against the rule's size and the hand-chosen one, per group:
    success, sizes and median times, from ``eval/voxel_advice.py --trial``'s rows."""
    rows = read_csv("voxel_advice_trial")
    groups = list(dict.fromkeys(r["group"] for r in rows))
    lines = []
    for group in [*groups, "all"]:
        mine = [r for r in rows if group in ("all", r["group"])]
        by = {c: [r for r in mine if r["choice"] == c] for c in ("hand", "suggested", "trial")}
        rate = {c: 100 * sum(r["success"] == "True" for r in v) / len(v) for c, v in by.items()}
        hand_mm = sorted({f"{1000 * float(r['voxel_m']):.0f}" for r in by["hand"]}, key=float)
        rule_mm = median([1000 * float(r["voxel_m"]) for r in by["suggested"]])
        sizes = [len(r["tried"].split(";")) for r in by["trial"]]
        seconds = [median([float(r["seconds"]) for r in by[c]])
                   for c in ("hand", "suggested", "trial")]
        lines.append([group, str(len(by["trial"])), ", ".join(hand_mm), f"{rule_mm:.1f}",
                      *(f"{rate[c]:.1f}%" for c in ("hand", "suggested", "trial")),
                      f"{rate['trial'] - rate['hand']:+.1f}",
                      f"{sum(n == 2 for n in sizes)} / {sum(n == 3 for n in sizes)}",
                      " / ".join(f"{t:.2f}" for t in seconds)])
    return "\n".join([
        table(["group", "n", "hand mm", "rule mm (median)", "hand success", "rule success",
               "trial success", "trial - hand, points", "trial: two sizes / three",
               "median s: hand / rule / trial"], lines),
        "",
        provenance("voxel_advice_trial") + " Success: symmetry-aware, 5 degrees and 1 cm; "
        "times (the registrations, as the script reports them) on 2 shared cores.",
    ])


#: Where ``eval/recall_generators.py`` can lose the truth, in the search's order.
RECALL_STAGES = ("candidates", "coarse", "confirmation", "ranking", "climbs", "ascent",
                 "polish")


def _percent(value: str) -> str:
    return "-" if value in ("", "nan") else f"{100 * float(value):.0f}%"


def _number(value: str, digits: int) -> str:
    return "-" if value in ("", "nan") else f"{float(value):.{digits}f}"


def recall() -> str:
    """The recall of each candidate generator per angle, and the stage of the search that
    loses the truth, from ``eval/recall_generators.py``'s summaries."""
    generators = [[r["dataset"], r["angle"], r["generator"], r["n"],
                   *(_percent(r[f"recall_at_{k}"]) for k in ("1", "4", "16", "all")),
                   _percent(r["placed"]), _number(r["median_placed_rank"], 0),
                   _number(r["median_nearest_deg"], 1)]
                  for r in read_csv("recall_generators")]
    stages = [[r["dataset"], r["angle"], r["n"],
               *(_percent(r[k]) for k in ("success", "final_right", "candidates_right",
                                          "placed_right")),
               f"{r['confirmed']} ({r['confirmed_wrong']})",
               _percent(r["confirmation_right"]), _percent(r["climbs_right"]),
               *(r[f"lost_{stage}"] for stage in RECALL_STAGES)]
              for r in read_csv("recall_stages")]
    return "\n".join([
        table(["dataset", "angle", "generator", "n", "recall@1", "recall@4", "recall@16",
               "recall@all", "a right one placed", "median placed rank",
               "median nearest (deg)"], generators),
        "",
        table(["dataset", "angle", "n", "success", "right at the end", "a right candidate",
               "a right one placed", "confirmed (wrong)", "confirmation's pose right",
               "climbs' best right", *(f"lost: {s}" for s in RECALL_STAGES)], stages),
        "",
        provenance("recall_generators") + " Right: within 10 degrees of the truth, "
        "symmetry-aware; success: 5 degrees and 1 cm; the stages in "
        "`docs/data/recall_stages.csv`, every pair in "
        "`docs/data/recall_pairs.csv`.",
    ])


def _counted(items: list[str]) -> str:
    """``"`a` (3), `b` (1)"``: each distinct item and how often, most often first."""
    counts = sorted(dict.fromkeys(items), key=lambda item: -items.count(item))
    return ", ".join(f"{item} ({items.count(item)})" for item in counts)


#: From these angles (degrees) the recall notes call turntable and dragon pairs far apart.
FAR_TURNTABLE, FAR_DRAGON = 90, 96


def _recall_run(dataset: str) -> tuple[dict[str, list[dict]], list[dict], list[dict]]:
    """The recall run's rows of ``dataset``: generators' rows by generator, stages' rows,
    pairs' rows."""
    generators: dict[str, list[dict]] = {}
    for r in read_csv("recall_generators"):
        if r["dataset"] == dataset:
            generators.setdefault(r["generator"], []).append(r)
    return (generators, [r for r in read_csv("recall_stages") if r["dataset"] == dataset],
            [r for r in read_csv("recall_pairs") if r["dataset"] == dataset])


def _column(rows: list[dict], key: str) -> list[float]:
    return [float(r[key]) for r in rows]


#: A wrong turntable pose within this many degrees of the turntable's angle is the view
#: turned as if the camera had not moved.
TURNED_BY_ANGLE = 15.0


def _recall_turntable() -> str:
    generators, stages, pairs = _recall_run("turntable")
    wrong = [r for r in pairs if r["success"] != "True" and int(r["angle"]) >= FAR_TURNTABLE]
    objects = _counted([r["pair"].rsplit("_", 1)[0] for r in wrong])
    lost = _counted([f"`{r['lost_at']}`" for r in wrong])
    offs = [abs(float(r["final_rotation_deg"]) - int(r["angle"])) for r in wrong]
    turned = [off for off in offs if off <= TURNED_BY_ANGLE]
    rest = sorted(float(r["final_rotation_deg"]) for r, off in zip(wrong, offs, strict=True)
                  if off > TURNED_BY_ANGLE)
    others = (f" (the other{'s' if len(rest) > 1 else ''} "
              f"{', '.join(f'{x:.0f}' for x in rest)} degrees off)") if rest else ""
    climbs = span(_column([r for r in stages if int(r["angle"]) >= FAR_TURNTABLE],
                             "climbs_right"), scale=100)
    recall = {g: span(_column(rows, "recall_at_all"), scale=100)
              for g, rows in generators.items()}
    return (
        f"On the turntable pairs the shells' peaks hold a right rotation on {recall['shell']}% "
        f"of pairs at every angle (the first placed at a median rank of "
        f"{span(_column(generators['shell'], 'median_placed_rank'))}), the EGI's on "
        f"{recall['egi']}%, the sweep's on {recall['sweep']}%, and the search ends right on "
        f"{span(_column(stages, 'success'), scale=100)}% of pairs at every angle. From "
        f"{FAR_TURNTABLE} degrees the wrong poses are, by object, {objects}; lost at {lost}; "
        f"{len(turned)} of {len(wrong)} turned from the truth by the turntable's angle, to "
        f"within {max(turned, default=0.0):.0f} degrees{others}. "
        f"There the climbs' best is right on {climbs}% of the pairs searched."
    )


def _recall_dragon() -> str:
    generators, stages, pairs = _recall_run("dragon")
    far = [r for r in pairs if int(r["angle"]) >= FAR_DRAGON]
    wrong = [r for r in far if r["success"] != "True"]
    lost = _counted([f"`{r['lost_at']}`" for r in wrong])

    def each(rows: list[dict], key: str) -> str:
        return ", ".join(f"{100 * v:.0f}" for v in _column(rows, key))

    return (
        f"On the dragon pairs {', '.join(r['angle'] for r in stages)} degrees apart the EGI's "
        f"peaks hold the rotation on {each(generators['egi'], 'recall_at_all')}% of pairs "
        f"(their nearest a median {span(_column(generators['egi'], 'median_nearest_deg'))} "
        f"degrees off), the shells' on {each(generators['shell'], 'recall_at_all')}%; the "
        f"climbs' best is right on {each(stages, 'climbs_right')}% of the pairs searched. From "
        f"{FAR_DRAGON} degrees {len(wrong)} of {len(far)} pairs end wrong, lost at {lost}: "
        f"the sweep's nearest rotation lies {span(_column(wrong, 'sweep_nearest_deg'))} "
        f"degrees off, and the climbs and the ascent from there leave them "
        f"{span(_column(wrong, 'final_rotation_deg'))} degrees off."
    )


def recall_notes() -> str:
    """The recall run read pair by pair: what holds the rotation, and where the wrong
    poses are lost when the scans are far apart."""
    return "\n".join([_recall_turntable(), "", _recall_dragon(), "", provenance("recall_pairs")])


def readme_speed() -> str:
    """README's time line: the speed bench's median ratios to the lean FPFH-RANSAC, as a
    range over views and scenes, over scan pairs, and on the 2 m tabletop."""
    ratios = {r["group"]: float(r["ratio_median"]) for r in read_csv("speed")}
    pairs = [g for g in ratios if g.startswith(("turntable", "dragon", "room"))]
    views = [g for g in ratios if g not in pairs and g != "wide"]

    def spread(groups: list[str]) -> str:
        values = [ratios[g] for g in groups]
        return f"{min(values):.1f}-{max(values):.1f}x"

    return "\n".join([
        table(["median time, one thread", "`registration_spectral_global`",
               "FPFH-RANSAC (ICP thinned to half the voxel)"],
              [["views and scenes / scan pairs / a view in a 2 m tabletop",
                f"{spread(views)} / {spread(pairs)} / {ratios['wide']:.2f}x", "1x"]]),
        "",
        provenance("speed") + " Per group: [docs/benchmarks.md](docs/benchmarks.md"
        "#speed-against-fpfh-ransac).",
    ])


#: ``eval/bench_multiway.py``'s pipelines, in its table's order.
MULTIWAY_PIPELINES = ("spectral", "fpfh_ransac_lean")


def multiway(source: str = "multiway") -> str:
    """Scans placed right of each set, and seconds per set, for both pipelines: from
    ``eval/bench_multiway.py``'s ``summary.csv`` (the stored output ``source``)."""
    rows = {(r["suite"], r["set"], r["pipeline"]): r for r in read_csv(source)}
    suites = list(dict.fromkeys(suite for suite, _, _ in rows))
    sets = sorted(dict.fromkeys((suite, name) for suite, name, _ in rows),
                  key=lambda key: (suites.index(key[0]), key[1] == "all"))
    lines = []
    for suite, name in sets:
        cells = []
        for pipeline in MULTIWAY_PIPELINES:
            r = rows[suite, name, pipeline]
            right, scans = int(r["right"]), int(r["scans"])
            cells += [f"{right}/{scans} ({100 * right / scans:.0f}%)", f"{float(r['seconds']):.1f}"]
        spectral = rows[suite, name, "spectral"]
        cells += [f"{spectral['doubtful']} ({spectral['doubtful_wrong']})",
                  spectral["wrong_undoubted"]]
        for pipeline in MULTIWAY_PIPELINES:
            r = rows[suite, name, pipeline]
            blind = r["right_without_cameras"]
            cells.append(f"{blind}/{r['scans']}" if blind else "-")
        lines.append([suite, f"**{name}**" if name == "all" else name, *cells])
    return "\n".join([
        table(["suite", "set", *(f"{p}: {k}" for p in MULTIWAY_PIPELINES for k in ("right", "s")),
               "spectral: doubtful (wrong)", "spectral: wrong, not doubtful",
               *(f"{p}: right without cameras" for p in MULTIWAY_PIPELINES)], lines),
        "",
        provenance(source) + " Every scan's errors: "
        f"`docs/data/{Path(sources()[source]['file']).parent}/rows.csv`.",
    ])


def servo_figures(name: str = "servo") -> dict[str, str]:
    """The figures of ``o3d-spectral servo --trials``' ``summary.json`` (source ``name``),
    formatted as the docs quote them."""
    f = json.loads((DATA / sources()[name]["file"]).read_text())
    return {
        "trials": str(f["trials"]), "successes": str(f["successes"]),
        "seeds": "-".join(map(str, f["seeds"])), "stopped": str(f["stopped_by_gradient_test"]),
        "mm": f"{f['final_translation_mm_median']:.2f} / {f['final_translation_mm_max']:.2f}",
        "deg": f"{f['final_rotation_deg_median']:.3f} / {f['final_rotation_deg_max']:.3f}",
        "cycles": f"{f['cycles_median']:.0f}", "all_cycles": str(f["cycles"]),
        "search_cycles": str(f["search_cycles"]), "violations": str(f["limit_violations"]),
        "ms": f"{f['controller_ms_median']:.0f}", "law_ms": f"{f['law_controller_ms_median']:.0f}",
        "search_s": f"{f['search_controller_s_min']:.1f}-{f['search_controller_s_max']:.1f}",
    }


def servo() -> str:
    """docs/servo.md's results table: the 30 seeded trials of the stored servo run."""
    f = servo_figures()
    return "\n".join([
        table(["measure", "value"], [
            ["success (final camera error <= 5 mm and <= 1 deg)",
             f"{f['successes']} of {f['trials']}"],
            ["stopped by the gradient test", f["stopped"]],
            ["final translation error, median / max (mm)", f["mm"]],
            ["final rotation error, median / max (deg)", f["deg"]],
            ["cycles, median", f["cycles"]],
            ["joint-limit violations (cycles)", f["violations"]],
            ["controller time per cycle (capture excluded), median",
             f"{f['ms']} ms (the law's cycles: {f['law_ms']} ms; {f['search_cycles']} of the "
             f"{f['all_cycles']} cycles ran the global search, {f['search_s']} s each)"]]),
        "",
        provenance("servo") + " Per trial: `docs/data/servo_trials.csv`.",
    ])


def servo_results() -> str:
    """results.md's servoing paragraph, from the stored servo run."""
    f = servo_figures()
    return (
        f"{f['successes']} of {f['trials']} trials end within 5 mm and 1 degree (final "
        f"errors median / max {f['mm']} mm and {f['deg']} deg) in {f['cycles']} cycles "
        f"median, the controller's time per cycle {f['ms']} ms median (the law's cycles "
        f"{f['law_ms']} ms, the global search's {f['search_s']} s). {provenance('servo')}"
    )


def servo_seed() -> str:
    """docs/servo.md's seed-0 trial (its figures are the run folder's ``seed_0000/``)."""
    r = next(r for r in read_csv("servo_trials") if r["seed"] == "0")
    return (
        f"Seed 0 of that run (`o3d-spectral servo --seed 0 --out out/servo` runs it alone): "
        f"{1000 * float(r['start_translation_m']):.0f} mm and "
        f"{float(r['start_rotation_deg']):.1f} deg away, "
        f"{100 * float(r['start_visible_fraction']):.0f}% of the first object in view at "
        f"the start; final {1000 * float(r['final_translation_m']):.2f} mm and "
        f"{float(r['final_rotation_deg']):.3f} deg after {float(r['time_s']):.1f} s "
        f"({r['cycles']} cycles). The figures below are its folder's (`seed_0000/`). "
        + provenance("servo_trials")
    )


def servo_unseen() -> str:
    """docs/servo.md's unseen seeds: the same run on the next 30 seeds, and the trials
    that fall short."""
    f, rows = servo_figures("servo_unseen"), read_csv("servo_unseen_trials")
    short = [r for r in rows if r["success"] != "True"]
    mm = [1000 * float(r["final_translation_m"]) for r in short]
    deg = [float(r["final_rotation_deg"]) for r in short]
    stopped = sum(r["converged"] == "True" for r in short)
    misses = (
        f": seeds {', '.join(r['seed'] for r in short)} end {min(mm):.1f}-{max(mm):.1f} mm "
        f"and {min(deg):.1f}-{max(deg):.1f} deg off, {stopped} of them stopped by the "
        f"gradient test (the law's fixed point on those scenes, not the truth)" if short else "")
    return (
        f"**Unseen seeds.** On seeds {f['seeds']}, not used to choose anything, "
        f"{f['successes']} of {f['trials']} end within 5 mm and 1 deg{misses}. "
        + provenance("servo_unseen")
    )


def readme_servo() -> str:
    """README's servoing line, from the stored servo run."""
    f = servo_figures()
    commit = sources()["servo"]["commit"]
    return (
        f"Simulated visual servoing of a KUKA iiwa, {f['trials']} random starts: "
        f"{f['successes']} of {f['trials']} within 5 mm and 1 deg, {f['ms']} ms a cycle "
        f"(median; measured at commit {commit}, stored in `docs/data/`; "
        f"[docs/servo.md](docs/servo.md))."
    )


def _width(rows: list[dict[str, str]]) -> str:
    """The width bench's result (its ``rows``): per method, median seconds at the narrowest
    and the widest scene and the successes per width; the width from which both
    FPFH-RANSACs are slower."""
    widths = sorted({float(r["width_m"]) for r in rows})
    names = {"spectral_global": "spectral", "fpfh_ransac_lean": "lean FPFH-RANSAC",
             "fpfh_ransac": "tutorial FPFH-RANSAC"}
    seconds, parts = {}, []
    for method, name in names.items():
        mine = [r for r in rows if r["method"] == method]
        at = [[r for r in mine if float(r["width_m"]) == w] for w in widths]
        seconds[method] = [median(float(r["seconds"]) for r in rs) for rs in at]
        wins = " / ".join(str(sum(r["success"] == "True" for r in rs)) for rs in at)
        parts.append(f"{name} {seconds[method][0]:.1f} s to {seconds[method][-1]:.1f} s "
                     f"({wins})")
    slower = [w for i, w in enumerate(widths) if all(
        seconds[m][j] > seconds["spectral_global"][j]
        for m in ("fpfh_ransac_lean", "fpfh_ransac") for j in range(i, len(widths)))]
    n = len({r["seed"] for r in rows})
    return (f"median {', '.join(parts)}: successes of {n} per width; both FPFH-RANSACs "
            + (f"slower from {slower[0]:g} m on" if slower else "faster at every width"))


def _prepared(name: str) -> tuple[float, str]:
    """Prepared once over prepared per call (ratio of the median totals), and the scans
    registered each way."""
    rows = read_csv(name)
    seconds = {p: median(float(r["seconds"]) for r in rows if r["prepared"] == p)
               for p in ("False", "True")}
    registered = "/".join(sorted({r["registered"] for r in rows}))
    return seconds["True"] / seconds["False"], f"{registered} / {rows[0]['scans']}"


def timings() -> str:
    """results.md's other timings: one law iteration, the width bench, a prepared model,
    two large clouds."""
    it, large, width = read_csv("iteration")[0], read_csv("large")[0], read_csv("width")
    points = sorted({int(r["scene_points"]) for r in width})
    widths = sorted({float(r["width_m"]) for r in width})
    estimated, given = _prepared("prepared_estimated"), _prepared("prepared_given")
    iteration = float(it["iteration_ms"])
    return "\n".join([
        table(["what", "result"], [
            [f"one iteration of the law ({it['object'].replace('_', ' ')}, "
             f"{1000 * float(it['voxel_m']):.0f} mm, B = {it['bandwidth']})",
             f"{iteration:.2f} ms (the paper: {float(it['paper_ms']):.1f} ms in C++), "
             f"{iteration / float(it['two_ffts_ms']):.2f} times two single-precision FFTs "
             f"of the grid"],
            [f"one view against tabletops {widths[0]:g}-{widths[-1]:g} m wide "
             f"({round(points[0], -3) // 1000}k-"
             f"{round(points[-1], -3) // 1000}k points)", _width(width)],
            [f"one model against {given[1].split(' / ')[-1]} views, prepared once or per call",
             f"{estimated[0]:.2f}x the time with estimated normals, {given[0]:.2f}x with given "
             f"ones; registered {estimated[1]} and {given[1]}"],
            [f"two clouds of {int(large['points']) / 1e6:g}M points, "
             f"{100 * float(large['voxel_m']):g} cm voxels, local call at the defaults "
             f"(every core)",
             f"{float(large['seconds']):.1f} s"]]),
        "",
        provenance("iteration", "width", "prepared_given", "prepared_estimated", "large"),
    ])


def far() -> str:
    """The pose errors of bench_far's cases at each distance from the origin: at 0 m, and
    the largest change over the distances."""
    rows = read_csv("far")
    keys = ("polished_deg", "polished_mm", "law_only_deg", "law_only_mm")
    lines = []
    for case in dict.fromkeys(r["case"] for r in rows):
        mine = [r for r in rows if r["case"] == case]
        spread = [max(float(r[k]) for r in mine) - min(float(r[k]) for r in mine) for k in keys]
        lines.append([case, f"{float(mine[0]['distance_m']):g}-{float(mine[-1]['distance_m']):g}",
                      *(f"{float(mine[0][k]):.3f}" for k in keys),
                      " / ".join(f"{x:.3f}" for x in spread)])
    return "\n".join([
        table(["case", "distances (m)", "polished: deg", "polished: mm", "law only: deg",
               "law only: mm", "largest change over the distances (same order)"], lines),
        "",
        provenance("far") + " Errors at the nearest distance, in the case's own frame.",
    ])


#: A view shows the handle when more than this share of its points lie on it.
SHOWS_HANDLE = 0.005


def handle_visibility() -> str:
    """The share of each view of the mug's turntable pairs on its handle, and the pairs
    in which a view shows none of it: from ``eval/handle_visibility.py``'s CSV."""
    rows = read_csv("handle_visibility")
    blind = [r for r in rows
             if min(float(r["source_share"]), float(r["target_share"])) <= SHOWS_HANDLE]
    angles = sorted({int(r["angle"]) for r in rows})
    undetermined = [a for a in angles
                    if all(r in blind for r in rows if int(r["angle"]) == a)]
    lines = [[r["angle"], r["elevation"], f"{100 * float(r['source_share']):.1f}%",
              f"{100 * float(r['target_share']):.1f}%"] for r in rows]
    return "\n".join([
        table(["degrees apart", "elevation", "source view on the handle",
               "target view on the handle"], lines),
        "",
        f"In {len(blind)} of the mug's {len(rows)} pairs a view shows none of the handle "
        f"(at most {100 * SHOWS_HANDLE:.1f}% of its points on it), among them every pair "
        f"{', '.join(str(a) for a in undetermined)} degrees apart. "
        + provenance("handle_visibility"),
    ])


def shapes() -> str:
    """Each stand-in shape's success with the global call and the lean FPFH-RANSAC, and
    the spectral call's wrong poses returned without a warning: from
    ``eval/bench_shapes.py``'s rows and summary."""
    rows, stored = read_csv("shapes_rows"), read_csv("shapes")
    summary = {(r["shape"], r["method"]): r for r in stored}
    lines = []
    for name in dict.fromkeys(r["shape"] for r in stored):
        mine = [r for r in rows if r["method"] == "spectral_global"
                and name in (r["shape"], "all")]
        silent = [r for r in mine if r["success"] == "False" and float(r["confidence"]) >= 0.5
                  and r["may_be_wrong_warning"] == "False"]
        spectral, lean = summary[name, "spectral_global"], summary[name, "fpfh_ransac_lean"]
        lines.append([name, spectral["n"], f"{100 * float(spectral['success']):.0f}%",
                      str(len(silent)), f"{float(spectral['median_s']):.2f}",
                      f"{100 * float(lean['success']):.0f}%", f"{float(lean['median_s']):.2f}"])
    return "\n".join([
        table(["shape", "views", "`registration_spectral_global`",
               "wrong, confidence >= 0.5, no warning", "median s", "lean FPFH-RANSAC",
               "median s"], lines),
        "",
        provenance("shapes") + " One thread per call on this 2-core machine; success "
        "symmetry-aware, 5 degrees and 1 cm at the model's centroid.",
    ])


def dense() -> str:
    """The adaptive, escalating (the CPU's default) and dense searches and the lean
    FPFH-RANSAC, per group: success and median seconds of each (``eval/bench_dense.py``'s
    summary)."""
    rows = read_csv("dense")
    by = {(r["group"], r["variant"]): r for r in rows}
    variants = ("adaptive", "escalating", "dense", "lean")
    lines = []
    for group in dict.fromkeys(r["group"] for r in rows):
        cells = [by[group, v] for v in variants]
        lines.append([group, cells[0]["n"],
                      *(f"{100 * float(c['success']):.0f}%" for c in cells),
                      *(f"{float(c['median_s']):.3f}" for c in cells),
                      f"{float(cells[2]['sweep_median_s']):.3f}"])
    names = ("adaptive", "escalating (default)", "dense", "lean FPFH")
    calls = read_csv("dense_rows")
    wrong = {v: [r for r in calls if r["variant"] == v and r["success"] == "False"]
             for v in variants[:3]}
    silent = {v: sum(float(r["confidence"]) >= 0.5 for r in wrong[v]) for v in wrong}
    escalated = sum(r["variant"] == "escalating" and float(r["sweep_s"]) > 0 for r in calls)
    return "\n".join([
        table(["group", "n", *(f"{n} success" for n in names),
               *(f"{n} median s" for n in names), "dense sweep median s"], lines),
        "",
        f"Over the {sum(r['variant'] == 'adaptive' for r in calls)} instances, wrong poses: "
        f"adaptive {len(wrong['adaptive'])}, escalating {len(wrong['escalating'])}, dense "
        f"{len(wrong['dense'])}; of those, returned with a confidence of one half or more "
        f"(no warning that the pose may be wrong): {silent['adaptive']}, "
        f"{silent['escalating']}, {silent['dense']}. The escalating search ran the dense "
        f"sweep in {escalated} calls.",
        "",
        provenance("dense") + " The three spectral searches and the lean FPFH-RANSAC at "
        "their defaults otherwise, on every core of this 2-core machine, each call timed "
        "once; success symmetry-aware, 5 degrees and 1 cm; the dense sweep: the stage "
        "`sweep` of the dense calls (0 where the first candidates were confirmed).",
    ])


def dense_cores() -> str:
    """The batched correlation per rotation on the dense search's two grids, and the
    whole dense sweep, on one worker and two (``eval/bench_correlation.py``'s rows)."""
    rows = read_csv("dense_cores")
    lines = [[r["group"], r["what"],
              "" if r["voxels"] in ("", "nan") else f"{float(r['voxels']):g}", r["fft"],
              f"{float(r['one']):.3f}", f"{float(r['many']):.3f}", r["unit"],
              f"{float(r['gain']):.2f}x", f"{100 * float(r['serial_share']):.0f}%",
              f"{100 * float(r['busy_one']):.0f}%", f"{100 * float(r['busy_many']):.0f}%",
              f"{float(r['cpu_ratio']):.2f}x"]
             for r in rows]
    return "\n".join([
        table(["group", "what", "voxels", "FFT", "1 worker", "2 workers", "unit", "gain",
               "not in parallel", "busy, 1", "busy, 2", "CPU per rotation"], lines),
        "",
        provenance("dense_cores") + " Medians of runs on one worker and on two in turn; "
        "not in parallel: the share of the one-worker time that the gain implies ran "
        "alone (Amdahl's law); busy: the process's CPU time over the workers' wall time "
        "(the rest they waited, for the last run or on the search's own steps); CPU per "
        "rotation: the CPU time two workers spent over what one spent on the same work "
        "(over 1x: each core did it slower, the two sharing memory and caches).",
    ])


def frontier() -> str:
    """Success against median time per kind of problem: each spectral search and each
    RANSAC setting (``eval/bench_dense.py --budgets ... --ransac ...``'s summary)."""
    rows = read_csv("frontier")
    kinds = {"views": ("full", "partial", "occluded", "ycbv_crop"),
             "scenes": ("cluttered", "crop_in_scene", "wide", "ycbv_frame"),
             "scan pairs": ("turntable_45", "turntable_90", "turntable_135",
                            "dragon_unoriented", "dragon_24", "dragon_48", "dragon_72",
                            "dragon_96", "dragon_120"),
             "model into scan": ("dragon_model",)}
    lines = []
    for kind, groups in kinds.items():
        for variant in dict.fromkeys(r["variant"] for r in rows):
            mine = [r for r in rows if r["variant"] == variant and r["group"] in groups]
            if not mine:
                continue
            n = sum(int(r["n"]) for r in mine)
            right = sum(float(r["success"]) * int(r["n"]) for r in mine)
            lines.append([kind, f"`{variant}`", str(n), f"{100 * right / n:.0f}%",
                          f"{median([float(r['median_s']) for r in mine]):.3f}"])
    return "\n".join([
        table(["kind", "variant", "n", "success", "median of the groups' median s"], lines),
        "",
        provenance("frontier") + " `dense_N`: `GlobalSearchOption(rotations=\"dense\", "
        "dense_rotations=N)`; `lean_I_C`: the lean FPFH-RANSAC stopped at `I` iterations or "
        "confidence `C` (`lean`: 100000 and 0.999, the tutorial's). Every call timed, right "
        "or wrong; on every core of this 2-core machine.",
    ])


#: Block name -> renderer. A block may appear in any of ``DOCS``.
BLOCKS: dict[str, Callable[[], str]] = {
    "readme": readme,
    "real-scans": real_scans,
    "suites-current": suites_current,
    "suites-all": suites_all,
    "c1": c1,
    "bop": bop,
    "pairs": pairs,
    "method-failures": method_failures,
    "confidence": confidence,
    "density": density,
    "speed": speed,
    "speed-change": speed_change,
    "cores-change": cores_change,
    "room-speed": lambda: speed("speed_room"),
    "cores": cores,
    "speed-stages": speed_stages,
    "settings": settings,
    "voxel-trial": voxel_trial,
    "readme-speed": readme_speed,
    "recall": recall,
    "multiway": multiway,
    "multiway-room": lambda: multiway("multiway_room"),
    "servo": servo,
    "servo-results": servo_results,
    "readme-servo": readme_servo,
    "servo-seed": servo_seed,
    "servo-unseen": servo_unseen,
    "timings": timings,
    "far": far,
    "recall-notes": recall_notes,
    "density-notes": density_notes,
    "confidence-misses": confidence_misses,
    "confidence-held-out": confidence_held_out,
    "handle-visibility": handle_visibility,
    "dense": dense,
    "shapes": shapes,
    "dense-cores": dense_cores,
    "frontier": frontier,
}
DOCS = (ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")))


def render(text: str) -> str:
    """``text`` with every figures block rewritten; ``KeyError`` for an unknown block."""
    def fill(match: re.Match) -> str:
        name = match.group(2)
        if name not in BLOCKS:
            raise KeyError(f"unknown figures block {name!r}; known: {sorted(BLOCKS)}")
        return f"{match.group(1)}{BLOCKS[name]()}\n{match.group(4)}"
    return BLOCK.sub(fill, text)


def rendered() -> dict[Path, tuple[str, str]]:
    """``{doc: (current text, rendered text)}`` for every doc holding a figures block."""
    out = {}
    for path in DOCS:
        text = path.read_text()
        if BLOCK.search(text):
            out[path] = (text, render(text))
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true",
                        help="change nothing; exit 1 if a doc differs from its stored outputs")
    args = parser.parse_args(argv)
    differ = 0
    for path, (text, new) in rendered().items():
        if text == new:
            continue
        differ += 1
        if args.check:
            sys.stdout.writelines(difflib.unified_diff(
                text.splitlines(keepends=True), new.splitlines(keepends=True),
                str(path.relative_to(ROOT)), "rendered from docs/data"))
        else:
            path.write_text(new)
            print(f"wrote {path.relative_to(ROOT)}")
    return 1 if args.check and differ else 0


if __name__ == "__main__":
    sys.exit(main())
