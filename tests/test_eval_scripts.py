"""Every script of ``eval/`` runs, on tiny inputs, and writes what it should.

Each script runs as a subprocess (``sys.executable eval/NAME.py ...``, in a temporary
folder) on a suite of one instance per condition, one group, one rotation, one repeat;
the test checks its exit code and the rows, columns or lines of its output. The scripts
that read another's output (``failure_signal``, ``confidence_precision``) read the tiny
runs of those here. :data:`SCRIPTS` lists them all: a script added to ``eval/`` without a
test here fails :func:`test_every_eval_script_has_a_tiny_run`.
"""

from __future__ import annotations

import csv
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import open3d as o3d
import pytest

from o3d_spectral.voxel.by_trial import VOXEL_LADDER

ROOT = Path(__file__).resolve().parents[1]
EVAL = ROOT / "eval"
BOP_YCBV = ROOT / "o3d_spectral" / "datasets" / "bop_ycbv"
CONDITIONS = ("full", "partial", "occluded", "cluttered")
#: Every script of ``eval/``, each run by the test ``test_<name>``.
SCRIPTS = (
    "bench_correlation.py",
    "bench_dense.py",
    "bench_density.py",
    "bench_far.py",
    "bench_iteration.py",
    "bench_large.py",
    "bench_multiway.py",
    "bench_prepared.py",
    "bench_pyramid.py",
    "bench_real.py",
    "bench_report.py",
    "bench_scaling.py",
    "bench_settings.py",
    "bench_shapes.py",
    "bench_speed.py",
    "bench_stages.py",
    "bench_width.py",
    "bop_poses.py",
    "c1_local.py",
    "calibrate_confidence.py",
    "check_unchanged.py",
    "confidence_precision.py",
    "derive_real_data.py",
    "device_check.py",
    "failure_signal.py",
    "fuzz_cli.py",
    "handle_visibility.py",
    "recall_generators.py",
    "room_fragments.py",
    "run_benchmark.py",
    "tune_fpfh.py",
    "voxel_advice.py",
)


def run(script: str, *args, cwd: Path, code: int = 0) -> str:
    """Run ``eval/<script>`` with ``args`` in ``cwd``; check its exit code is ``code``
    and return its standard output."""
    done = subprocess.run(
        [sys.executable, str(EVAL / script), *map(str, args)], cwd=cwd, capture_output=True,
        text=True, timeout=600, env=os.environ | {"MPLBACKEND": "Agg"}, check=False)
    assert done.returncode == code, (
        f"{script} exited {done.returncode}, not {code}\n{done.stdout[-2000:]}\n"
        f"{done.stderr[-4000:]}")
    return done.stdout


def read_csv(path: Path) -> list[dict]:
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def table_rows(text: str, first: str) -> list[list[str]]:
    """The cells of the Markdown table rows of ``text`` whose first cell is ``first``."""
    rows = [[cell.strip() for cell in line.strip().strip("|").split("|")]
            for line in text.splitlines() if line.startswith("|")]
    return [row for row in rows if row[0] == first]


@pytest.fixture(scope="session")
def suites(tmp_path_factory) -> Path:
    """The four suites of one instance each (seed 0), as ``run_benchmark.py`` makes them."""
    from o3d_spectral.synthetic.suite import make_suite

    root = tmp_path_factory.mktemp("suites")
    for condition in CONDITIONS:
        make_suite(condition, 1, 0, root / condition, progress=False)
    return root


@pytest.fixture(scope="module")
def speed_run(suites, tmp_path_factory) -> tuple[Path, str]:
    """``bench_speed.py`` on the full suite's instance: (its folder, its output)."""
    out = tmp_path_factory.mktemp("bench_speed")
    printed = run("bench_speed.py", "--suites", suites, "--groups", "full", "--limit", 1,
                  "--repeats", 1, "--out", out, cwd=out)
    return out, printed


@pytest.fixture(scope="module")
def real_run(tmp_path_factory) -> Path:
    """``bench_real.py`` on one YCB-Video crop, one rotation, no normals: its folder."""
    out = tmp_path_factory.mktemp("bench_real")
    run("bench_real.py", "--out", out, "--rotations", 1, "--workers", 1, "--groups",
        "ycbv_crop", "--modes", "none", "--limit", 1, cwd=out)
    return out


@pytest.fixture(scope="module")
def benchmark_run(suites, tmp_path_factory) -> Path:
    """``run_benchmark.py`` with ``spectral_global`` on the four tiny suites: its folder
    (``run``, ``report``, ``results.md``)."""
    out = tmp_path_factory.mktemp("run_benchmark")
    (out / "results.md").write_text(
        "# Results\n<!-- BEGIN GENERATED: by run_benchmark.py -->\nold\n"
        "<!-- END GENERATED -->\nkept\n")
    run("run_benchmark.py", "--n", 1, "--workers", 1, "--methods", "spectral_global",
        "--suites-dir", suites, "--out", out / "run", "--figures", out / "report",
        "--docs", out / "results.md", cwd=out)
    return out


def test_every_eval_script_has_a_tiny_run():
    assert {p.name for p in EVAL.glob("*.py")} == set(SCRIPTS)
    tests = {name for name in globals() if name.startswith("test_")}
    assert {f"test_{Path(s).stem}" for s in SCRIPTS} <= tests


def test_handle_visibility(tmp_path):
    """Every mug pair of the recall tables, the share of each view on the handle: none in
    one view of every pair 30-60 degrees apart, some in both at 120 degrees and 20 of
    elevation."""
    printed = run("handle_visibility.py", "--out", tmp_path / "shares.csv", cwd=tmp_path)
    rows = read_csv(tmp_path / "shares.csv")
    assert len(rows) == 12 and len(table_rows(printed, "30")) == 2
    shares = {(int(r["angle"]), int(r["elevation"])): (float(r["source_share"]),
                                                      float(r["target_share"])) for r in rows}
    assert all(0.0 <= s <= 1.0 for pair in shares.values() for s in pair)
    assert all(min(shares[angle, elevation]) <= 0.005 for angle in (30, 45, 60)
               for elevation in (20, 45))
    assert min(shares[120, 20]) > 0.01


def test_bench_shapes(tmp_path):
    """One view of a flat can and of a marker against the global call and the lean
    FPFH-RANSAC: a row per call with symmetry-aware errors, the summary per shape and
    overall, the same instances in a second run (only the times differ)."""
    args = ("--out", tmp_path / "a", "--views", 1, "--shapes", "tuna_can", "marker")
    printed = run("bench_shapes.py", *args, cwd=tmp_path)
    rows = read_csv(tmp_path / "a" / "rows.csv")
    assert [(r["shape"], r["method"]) for r in rows] == [
        (shape, method) for shape in ("tuna_can", "marker")
        for method in ("spectral_global", "fpfh_ransac_lean")]
    assert all(0.0 <= float(r["rotation_error_deg"]) <= 180.0 for r in rows)
    assert all(r["success"] in ("True", "False") and int(r["target_points"]) >= 300
               for r in rows)
    assert all(0.0 <= float(r["confidence"]) <= 1.0 for r in rows
               if r["method"] == "spectral_global")
    summary = read_csv(tmp_path / "a" / "summary.csv")
    assert [r["shape"] for r in summary] == ["tuna_can"] * 2 + ["marker"] * 2 + ["all"] * 2
    assert [int(r["n"]) for r in summary] == [1, 1, 1, 1, 2, 2]
    assert len(table_rows(printed, "all")) == 1
    run("bench_shapes.py", *args[:1], tmp_path / "b", *args[2:], cwd=tmp_path)
    again = read_csv(tmp_path / "b" / "rows.csv")
    for key in ("target_points", "rotation_error_deg", "translation_error_m", "success"):
        assert [r[key] for r in again] == [r[key] for r in rows]
    run("bench_shapes.py", "--out", tmp_path / "c", "--views", 0, cwd=tmp_path, code=2)


@pytest.mark.slow
def test_device_check(tmp_path):
    """Inputs prepared for a turntable pair, then the check with NumPy as the device's
    library: the same peaks, and the times written."""
    run("device_check.py", "prepare", "--groups", "turntable_135", "--repeats", 1, "--out",
        tmp_path / "inputs", cwd=tmp_path)
    with np.load(tmp_path / "inputs" / "turntable_135.npz") as data:
        assert data["rotations"].shape[1:] == (3, 3) and len(data["rotations"]) > 1000
    printed = run("device_check.py", "run", "--inputs", tmp_path / "inputs", "--out",
                  tmp_path / "out", "--xp", "numpy", "--repeats", 1, cwd=tmp_path)
    (row,) = json.loads((tmp_path / "out" / "results.json").read_text())["rows"]
    assert row["max_relative_difference"] == 0.0 and row["same_first"]
    assert row["sweep_s"] > 0 and row["ratio_to_lean"] > 0
    assert "| turntable_135 (" in printed


def test_fuzz_cli(tmp_path):
    """The stream probes, and SIGTERM / SIGINT to ``convert`` once it has started."""
    printed = run("fuzz_cli.py", "--probes", "streams", "signals", "--commands", "convert",
                  "--moments", 0.6, "--out", tmp_path / "fuzz", cwd=tmp_path)
    lines = printed.strip().splitlines()
    assert len(lines) == 7 and all(line.startswith("ok ") for line in lines[:-1]), printed
    assert lines[-1].startswith("6 of 6 probes held")


def test_bench_correlation(tmp_path):
    """One turntable pair: both grids of the dense search per rotation, then the sweep,
    each on one worker and two."""
    printed = run("bench_correlation.py", "--groups", "turntable_45", "--count", 16,
                  "--dense-count", 64, "--repeats", 1, "--out", tmp_path, cwd=tmp_path)
    rows = read_csv(tmp_path / "rows.csv")
    assert [r["what"] for r in rows] == ["coarse grid", "fine grid", "dense sweep"]
    assert all(float(r["one"]) > 0 and float(r["many"]) > 0 and float(r["gain"]) > 0
               for r in rows)
    assert [r["unit"] for r in rows] == ["ms/rotation", "ms/rotation", "s"]
    assert len(table_rows(printed, "turntable_45")) == 3


def test_bench_dense(tmp_path):
    """One turntable pair, every variant once: a row each, a summary line each, the
    figure, and the figure again from the stored summary."""
    printed = run("bench_dense.py", "--groups", "turntable_45", "--limit", 1, "--budgets", 300,
                  "--ransac", "100:0.9", "--figure", "--out", tmp_path, cwd=tmp_path)
    rows = read_csv(tmp_path / "rows.csv")
    assert [r["variant"] for r in rows] == ["adaptive", "escalating", "dense", "dense_300",
                                            "lean", "lean_100_0.9"]
    assert all(float(r["seconds"]) > 0 and r["success"] in ("True", "False") for r in rows)
    spectral, lean = rows[:4], rows[4:]  # the spectral calls' evidence; none for RANSAC
    assert all(0 < float(r[k]) <= 1 for r in spectral for k in ("confidence", "fit", "fitness"))
    assert all(r[k] == "nan" for r in lean for k in ("confidence", "fit", "fitness"))
    summary = read_csv(tmp_path / "summary.csv")
    assert [(s["group"], s["n"]) for s in summary] == [("turntable_45", "1")] * 6
    assert table_rows(printed, "turntable_45")
    again = tmp_path / "again"
    run("bench_dense.py", "--figure-from", tmp_path / "summary.csv", "--out", again,
        cwd=tmp_path)
    for folder in (tmp_path, again):
        assert all((folder / f).stat().st_size > 0
                   for f in ("frontier.png", "frontier_groups.png"))


def test_bench_density(tmp_path):
    printed = run("bench_density.py", "--limit", 1, "--scales", 1, 2, "--repeats", 1, "--out",
                  tmp_path, cwd=tmp_path)
    rows = read_csv(tmp_path / "density.csv")
    assert [(r["multiplier"], r["method"]) for r in rows] == [
        (m, method) for m in ("1", "4") for method in ("spectral_global", "fpfh_ransac_lean")]
    assert len({r["azimuth_deg"] for r in rows}) == 1  # the same pose at every density
    assert int(rows[2]["target_points"]) > 3 * int(rows[0]["target_points"])
    assert {"seconds", "success", "prepare_s", "polish_s"} <= rows[0].keys()
    summary = read_csv(tmp_path / "summary.csv")
    assert [(s["multiplier"], s["method"]) for s in summary] == [
        ("1", "spectral_global"), ("4", "spectral_global"), ("1", "fpfh_ransac_lean"),
        ("4", "fpfh_ransac_lean")]
    assert float(summary[0]["median_ratio_to_1x"]) == 1.0
    assert [row[:2] for row in table_rows(printed, "4x")][0] == ["4x", "spectral global"]
    assert (tmp_path / "density.png").stat().st_size > 0


def test_bench_far(tmp_path):
    run("bench_far.py", "--cases", "mustard_model", "--distances", 0, 1000, "--out",
        tmp_path / "far.md", "--csv", tmp_path / "far.csv", cwd=tmp_path)
    text = (tmp_path / "far.md").read_text()
    assert text.startswith("**mustard_model**")
    assert [len(table_rows(text, d)) for d in ("0", "1000", "spread")] == [1, 1, 1]
    assert len(table_rows(text, "spread")[0]) == 5
    rows = read_csv(tmp_path / "far.csv")
    assert [(r["case"], float(r["distance_m"])) for r in rows] == [
        ("mustard_model", 0.0), ("mustard_model", 1000.0)]
    assert f"{float(rows[1]['polished_deg']):.3f}" == table_rows(text, "1000")[0][1]


def test_bench_iteration(tmp_path):
    printed = run("bench_iteration.py", "--iterations", 3, "--runs", 1, "--out",
                  tmp_path / "iteration.csv", cwd=tmp_path)
    assert re.search(r"one iteration \(median\)\s+\d+\.\d\d", printed)
    assert re.search(r"two 3D FFTs of the same grid\s+\d+\.\d\d", printed)
    assert "iteration / two FFTs = " in printed
    [row] = read_csv(tmp_path / "iteration.csv")
    assert (row["object"], row["bandwidth"], row["iterations"]) == ("mustard_bottle", "16", "3")
    assert f"{float(row['iteration_ms']):.2f}" in printed


def test_bench_large(tmp_path):
    printed = run("bench_large.py", "--points", 20000, "--profile", "--out",
                  tmp_path / "large.csv", cwd=tmp_path)
    assert re.search(r"^20000 points: [\d.]+ s; error [\d.]+ deg, [\d.]+ mm; fitness", printed,
                     re.MULTILINE)
    assert re.search(r"^  climb\s+[\d.]+ s$", printed, re.MULTILINE)
    [row] = read_csv(tmp_path / "large.csv")
    assert (row["points"], row["profiled"]) == ("20000", "True")
    assert f"{float(row['seconds']):.1f} s" in printed


def test_bench_multiway(tmp_path):
    printed = run("bench_multiway.py", "--limit-scans", 3, "--models", 1, "--seeds", 1,
                  "--workers", 1, "--out", tmp_path, cwd=tmp_path)
    rows = read_csv(tmp_path / "rows.csv")
    assert [(r["suite"], r["pipeline"]) for r in rows] == [
        (suite, pipeline) for suite in ("dragon", "turntable")
        for pipeline in ("spectral", "fpfh_ransac_lean") for _ in range(3)]
    assert {"rotation_error_deg", "translation_error_m", "success"} <= rows[0].keys()
    assert [row[1] for row in table_rows(printed, "dragon")] == ["seed 0", "**all**"]
    assert printed.endswith((tmp_path / "table.md").read_text())


def test_bench_multiway_registers_a_rooms_fragments(tmp_path):
    run("bench_multiway.py", "--seeds", 0, "--models", 0, "--rooms", 1, "--limit-scans", 3,
        "--workers", 1, "--out", tmp_path, cwd=tmp_path)
    rows = read_csv(tmp_path / "rows.csv")
    assert [(r["suite"], r["set"], r["scan"]) for r in rows] == [
        ("room", "room 300", str(k)) for _ in ("spectral", "fpfh_ransac_lean") for k in range(3)]
    assert rows[0]["success"] == "True"  # the first scan is the frame: placed exactly


def test_room_fragments(tmp_path):
    """A small room written in the 3DMatch layout reads back as its pairs, each truth
    recalled exactly (``gt.log`` holds 11 significant digits; the angle's arccos reads
    them to ~1e-4 degree)."""
    from o3d_spectral.harness.pairs import PairSet

    run("room_fragments.py", "--seeds", 7, "--fragments", 8, "--frames-per-fragment", 2,
        "--frame-step", 20.0, "--spacing", 0.02, "--out", tmp_path, cwd=tmp_path)
    pairs = PairSet(tmp_path / "room_7")
    assert len(pairs) >= 2
    for index in range(len(pairs)):
        score = pairs.score(pairs[index].T_gt, index)
        assert score["recalled"] and score["rmse_recalled"]
        assert score["re_deg"] < 1e-3 and score["te_m"] < 1e-9 and score["rmse_m"] < 1e-6


def test_bench_prepared(suites, tmp_path):
    from o3d_spectral.synthetic.suite import load_suite

    name = load_suite(suites / "partial")[0].object
    printed = run("bench_prepared.py", "--suite", suites / "partial", "--object", name,
                  "--repeats", 1, "--out", tmp_path / "prepared.csv", cwd=tmp_path)
    assert [row[:3] for row in table_rows(printed, name)] == [[name, "given", "1"]]
    assert re.search(r"prepared=True: [\d.]+ s, \d of 1 registered", printed)
    rows = read_csv(tmp_path / "prepared.csv")
    assert [(r["normals"], r["repeat"], r["prepared"], r["scans"]) for r in rows] == [
        ("given", "0", "False", "1"), ("given", "0", "True", "1")]


def test_bench_pyramid(suites, tmp_path):
    printed = run("bench_pyramid.py", "--groups", "full", "--suites", suites, "--limit", 1,
                  "--rotations", 1, "--counts", 8, "--view-pairs", 0, cwd=tmp_path)
    recall = [row for row in (r.split("|") for r in printed.splitlines())
              if row[1:2] and row[1].strip().startswith("model and view (")]
    assert [row[2].strip() for row in recall] == ["4", "2", "1"]
    assert re.fullmatch(r"[01]/1", table_rows(printed, "8")[0][1])


def test_bench_real(real_run):
    rows = read_csv(real_run / "rows.csv")
    assert [(r["group"], r["mode"], r["method"]) for r in rows] == [
        ("ycbv_crop", "none", "spectral_global"), ("ycbv_crop", "none", "fpfh_ransac")]
    assert {"seconds", "rotation_error_deg", "success", "transformation",
            "confidence"} <= rows[0].keys()
    assert len(rows[0]["transformation"].split()) == 16
    summary = read_csv(real_run / "summary.csv")
    assert [(s["group"], s["n"]) for s in summary] == [("ycbv_crop", "1")]
    assert table_rows((real_run / "summary.md").read_text(), "ycbv_crop")


def test_bench_report(tmp_path):
    printed = run("bench_report.py", "--out", tmp_path, "--instances", 1, cwd=tmp_path)
    assert re.match(r"report of 48 rows: [\d.]+ s wall", printed)
    assert (tmp_path / "fake_run" / "results.jsonl").read_text().count("\n") == 48
    assert (tmp_path / "report" / "report.md").is_file()


def test_bench_scaling(tmp_path):
    run("bench_scaling.py", "--points", 1000, "--voxels", 0.016, "--out", tmp_path,
        "--figure", tmp_path / "scaling.png", cwd=tmp_path)
    rows = read_csv(tmp_path / "scaling.csv")
    assert [(r["sweep"], r["voxel_m"]) for r in rows] == [("points", "0.008"),
                                                          ("voxel", "0.016")]
    assert rows[0]["target_points"] == "1000" and "spectral_global_s" in rows[0]
    assert (tmp_path / "scaling.png").stat().st_size > 0


def test_bench_speed(speed_run):
    out, printed = speed_run
    rows = read_csv(out / "instances.csv")
    assert [r["group"] for r in rows] == ["full"] * len(rows)
    assert rows[0]["method"] == "spectral_global" and len({r["method"] for r in rows}) >= 2
    assert {"seconds", "success", "fitness", "may_be_wrong_warning", "confirmed"} <= rows[0].keys()
    summary = read_csv(out / "summary.csv")
    assert [(s["group"], s["n"]) for s in summary] == [("full", "1")]
    assert table_rows(printed, "full") and (out / "summary.md").is_file()


def test_bench_stages(suites, tmp_path):
    from o3d_spectral.common.stages import GLOBAL_STAGES

    printed = run("bench_stages.py", "--suites", suites, "--groups", "full", "--limit", 1,
                  "--out", tmp_path, cwd=tmp_path)
    rows = read_csv(tmp_path / "stages.csv")
    assert [r["group"] for r in rows] == ["full"]
    assert {*GLOBAL_STAGES, "total"} <= rows[0].keys()
    assert table_rows(printed, "full (1)")


def test_bench_settings(suites, tmp_path):
    """Two settings on the full suite's instance: a row per call, a summary whose
    defaults line compares the defaults with themselves (ratio 1, nothing lost or won),
    and the same summary again from the stored rows."""
    printed = run("bench_settings.py", "--suites", suites, "--groups", "full", "--limit", 1,
                  "--settings", "climbs=2", "--out", tmp_path, cwd=tmp_path)
    rows = read_csv(tmp_path / "rows.csv")
    assert [(r["group"], r["setting"]) for r in rows] == [("full", "defaults"),
                                                          ("full", "climbs=2")]
    summary = {(s["setting"], s["kind"]): s for s in read_csv(tmp_path / "summary.csv")}
    assert set(summary) == {(s, k) for s in ("defaults", "climbs=2") for k in ("views", "all")}
    defaults = summary["defaults", "all"]
    assert (float(defaults["time_ratio_median"]), defaults["lost"], defaults["won"]) == (
        1.0, "0", "0")
    assert table_rows(printed, "climbs=2")
    again = tmp_path / "again"
    run("bench_settings.py", "--from-rows", tmp_path / "rows.csv", "--out", again, cwd=tmp_path)
    assert read_csv(again / "summary.csv") == read_csv(tmp_path / "summary.csv")


def test_bench_width(tmp_path):
    run("bench_width.py", "--widths", 0.25, "--seeds", 1, "--out", tmp_path, "--figure",
        tmp_path / "width.png", cwd=tmp_path)
    rows = read_csv(tmp_path / "width.csv")
    assert [r["method"] for r in rows][0] == "spectral_global" and len(rows) >= 2
    assert {r["width_m"] for r in rows} == {"0.25"}
    assert (tmp_path / "width.png").stat().st_size > 0
    run("bench_width.py", "--plot", tmp_path / "width.csv", "--figure", tmp_path / "again.png",
        cwd=tmp_path)
    assert (tmp_path / "again.png").stat().st_size > 0


def test_bop_poses(tmp_path):
    from o3d_spectral.cli import main

    bop_run = tmp_path / "bop_run"
    assert main(["-q", "eval", "--bop", str(BOP_YCBV), "--objects", "14", "--limit", "1",
                 "--methods", "icp_point_to_plane", "--out", str(bop_run)]) == 0
    printed = run("bop_poses.py", bop_run, "--dataset", BOP_YCBV, "--object", 14,
                  cwd=tmp_path)
    methods = [row[:2] for row in table_rows(printed, "bop_ycbv_test_crop")
               + table_rows(printed, "bop_ycbv_test_frame")]
    assert methods == [["bop_ycbv_test_crop", "icp_point_to_plane"],
                       ["bop_ycbv_test_frame", "icp_point_to_plane"]]
    # the true pose itself: no VSD error, every recall 1
    assert table_rows(printed, "0") == [["0", "0.00 / 0.00 / 0.00", "0.0", "1.00", "1.00",
                                         "1.00"]]
    assert all(len(table_rows(printed, turn)) == 1 for turn in ("5", "10", "20", "45", "90",
                                                                 "180"))


def test_c1_local(tmp_path):
    printed = run("c1_local.py", "--cases", 1, cwd=tmp_path)
    assert re.match(r"C-1 local, moved copy, default settings: \d/6 = ", printed)
    names = [line.split()[0] for line in printed.splitlines()[2:]]
    assert names == ["mustard_bottle", "power_drill", "mug", "cracker_box", "banana",
                     "scissors", "all"]


def test_calibrate_confidence(tmp_path):
    """Two units of three groups (a right view, a half crop, a wrong object): one of each
    fits, one is held back; the refit from the stored rows prints the same tables; held
    back by object, each object's rows are one fold, refitted on the other's."""
    out = tmp_path / "out"
    printed = run("calibrate_confidence.py", "--out", out, "--groups", "partial",
                  "half_crop", "wrong_object", "--per-group", 2, cwd=tmp_path)
    rows = read_csv(out / "rows.csv")
    assert [r["group"] for r in rows] == ["partial"] * 2 + ["half_crop"] * 2 + ["wrong_object"] * 2
    assert {"right", "confidence", "fit", "target_fit", "free_space", "ambiguous"} <= rows[0].keys()
    assert all(r["right"] == "0" for r in rows[4:])  # every pose of a wrong object is wrong
    summary = read_csv(out / "summary.csv")
    assert [(s["confidence"], s["part"], s["n"]) for s in summary] == [
        ("library", "held back", "3"), ("library", "fitting", "3"),
        ("refit", "held back", "3"), ("refit", "fitting", "3")]
    groups = read_csv(out / "groups.csv")
    assert [(g["group"], g["n"]) for g in groups] == [("partial", "1"), ("half_crop", "1"),
                                                       ("wrong_object", "1")]
    assert (out / "reliability.png").stat().st_size > 0
    assert len(read_csv(out / "reliability.csv")) == 10
    assert len(table_rows(printed, "library")) == 2
    again = run("calibrate_confidence.py", "--out", tmp_path / "again", "--rows",
                out / "rows.csv", cwd=tmp_path)
    assert table_rows(again, "library") == table_rows(printed, "library")
    silent = read_csv(out / "silent.csv")[0]
    assert int(silent["calls"]) == 6 and int(silent["wrong"]) >= 2
    assert 0 <= int(silent["silent_wrong"]) <= int(silent["wrong"])
    by_object = tmp_path / "by_object"
    run("calibrate_confidence.py", "--out", by_object, "--rows", out / "rows.csv",
        "--split", "object", cwd=tmp_path)
    folds = read_csv(by_object / "folds.csv")
    assert [(f["fold"], f["n"]) for f in folds] == [("banana", "3"), ("bowl", "3")]
    assert [(s["confidence"], s["part"], s["n"]) for s in read_csv(by_object / "summary.csv")] == [
        ("refit", "each object held back", "6"), ("library", "each object held back", "6")]


def test_check_unchanged(suites, tmp_path):
    """A recording, then a comparison with it changed by 1 mm in one call: that call's
    instance is reported over the tolerance (exit 1), the other's difference is 0."""
    run("check_unchanged.py", "--suites", suites, "--groups", "full", "--count", 1,
        "--record", tmp_path / "recorded.npz", cwd=tmp_path)
    recorded = dict(np.load(tmp_path / "recorded.npz"))
    assert recorded["full/local"].shape == recorded["full/global"].shape == (1, 4, 4)
    changed = recorded | {"full/local": recorded["full/local"] + 1e-3}
    np.savez_compressed(tmp_path / "changed.npz", **changed)
    printed = run("check_unchanged.py", "--suites", suites, "--groups", "full", "--count", 1,
                  "--compare", tmp_path / "changed.npz", "--save", tmp_path / "again.npz",
                  cwd=tmp_path, code=1)
    assert re.search(r"full/global\s+1 instances  max \|difference\| 0  \(0 over 1e-09\)",
                     printed)
    assert re.search(r"full/local\s+1 instances  max \|difference\| 0.001  \(1 over", printed)
    again = np.load(tmp_path / "again.npz")
    for key in ("full/local", "full/global"):  # the same poses, run after run
        np.testing.assert_array_equal(again[key], recorded[key])


def test_confidence_precision(benchmark_run, real_run, tmp_path):
    printed = run("confidence_precision.py", "--run", benchmark_run / "run", "--real",
                  real_run / "rows.csv", cwd=tmp_path)
    for group in (*CONDITIONS, "ycbv_crop (none)"):
        assert table_rows(printed, group)[0][1] == "1"
    assert [row[1] for row in table_rows(printed, "all")] == ["4", "1"]


def test_derive_real_data(tmp_path):
    from o3d_spectral.harness.real import YCBV_CLASSES, real_dir
    from tests.real_originals import write_originals

    originals = write_originals(tmp_path / "originals")
    out = tmp_path / "real"
    run("derive_real_data.py", originals, "--out", out, cwd=tmp_path)
    printed = sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.is_file())
    bundled = sorted(str(p.relative_to(real_dir())) for p in real_dir().rglob("*")
                     if p.is_file() and p.name != "README.md")
    assert printed == bundled

    def points(path: Path) -> np.ndarray:
        return np.asarray(o3d.io.read_point_cloud(str(path)).points)

    frame = Path("ycbv") / "0000_000001"
    same = [Path("dragon") / "dragonStandRight_24.ply", *(Path("ycbv") / "models" / f"{n}.ply"
                                                         for n in YCBV_CLASSES),
            frame / f"{YCBV_CLASSES[0]}_crop.ply"]
    for name in same:  # float32 points in, the same float32 points out
        np.testing.assert_array_equal(points(out / name), points(real_dir() / name))
    scene = points(out / frame / "scene_2mm.ply")
    assert 0 < len(scene) < len(points(originals / "ycbv" / "0000_000001" / "scene.ply"))


def test_failure_signal(speed_run, tmp_path):
    """The rows of bench_speed, and a crafted group of two wrong poses, one flagged by the
    warning, both by fitness under 0.5 and 0.7: the table counts them."""
    rows = read_csv(speed_run[0] / "instances.csv")
    crafted = [rows[0] | {"group": "crafted", "success": "False", "fitness": fitness,
                          "may_be_wrong_warning": warned}
               for fitness, warned in (("0.4", "True"), ("0.45", "False"))]
    path = tmp_path / "instances.csv"
    with open(path, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows + crafted)
    printed = run("failure_signal.py", path, cwd=tmp_path)
    assert table_rows(printed, "crafted") == [
        ["crafted", "2", "2", "may-be-wrong warning", "1", "100%", "50%"],
        ["crafted", "2", "2", "fitness < 0.3", "0", "-", "0%"],
        ["crafted", "2", "2", "fitness < 0.5", "2", "100%", "100%"],
        ["crafted", "2", "2", "fitness < 0.7", "2", "100%", "100%"],
    ]
    assert [row[1] for row in table_rows(printed, "full")] == ["1"] * 4


def test_recall_generators(tmp_path):
    printed = run("recall_generators.py", "--angles", 90, 24, "--limit", 1, "--rotations", 1,
                  "--out", tmp_path, cwd=tmp_path)
    pairs = read_csv(tmp_path / "pairs.csv")
    assert [(r["dataset"], r["angle"]) for r in pairs] == [("turntable", "90"), ("dragon", "24")]
    assert {"egi_first_right", "sweep_placed_rank", "lost_at", "success"} <= pairs[0].keys()
    generators = read_csv(tmp_path / "generators.csv")
    assert [g["generator"] for g in generators] == ["egi", "shell", "sweep"] * 2
    assert {"recall_at_1", "recall_at_all", "median_placed_rank"} <= generators[0].keys()
    stages = read_csv(tmp_path / "stages.csv")
    assert [(s["dataset"], s["n"]) for s in stages] == [("turntable", "1"), ("dragon", "1")]
    assert table_rows(printed, "turntable") and (tmp_path / "summary.md").is_file()
    run("recall_generators.py", "--angles", 91, "--out", tmp_path, cwd=tmp_path, code=2)


def test_run_benchmark(benchmark_run):
    rows = read_csv(benchmark_run / "run" / "results.csv")
    assert sorted((r["suite"], r["method"]) for r in rows) == sorted(
        (c, "spectral_global") for c in CONDITIONS)
    docs = (benchmark_run / "results.md").read_text()
    assert "\nold\n" not in docs and docs.endswith("<!-- END GENERATED -->\nkept\n")
    assert "Produced by `python eval/run_benchmark.py --n 1 " in docs
    assert (benchmark_run / "report" / "report.md").is_file()


def test_tune_fpfh(suites, tmp_path):
    from o3d_spectral.harness.peers import FPFH_TUNING_GRID

    printed = run("tune_fpfh.py", "--suites", suites / "full", "--per-suite", 1, "--workers", 1,
                  cwd=tmp_path)
    lines = printed.splitlines()
    pairs = len(list(FPFH_TUNING_GRID.values())[0]) * len(list(FPFH_TUNING_GRID.values())[1])
    assert lines[0].split()[:3] == ["feature_r", "normal_r", "full"]
    assert len(lines) == pairs + 2
    assert re.match(r"best on 1 tuning instances: feature_radius_voxels=[\d.]+, "
                    r"normal_radius_voxels=[\d.]+$", lines[-1])


def test_voxel_advice(suites, tmp_path):
    out = tmp_path / "out"
    printed = run("voxel_advice.py", "--suites", suites, "--groups", "full", "--limit", 1,
                  "--out", out, cwd=tmp_path)
    rows = read_csv(out / "rows.csv")
    assert [(r["group"], r["choice"]) for r in rows] == [("full", "hand"),
                                                         ("full", "suggested")]
    assert rows[0]["voxel_m"] == "0.008"
    tables = (out / "tables.md").read_text()
    assert printed == tables and len(table_rows(tables, "full")) == 3
    shutil.copyfile(out / "rows.csv", tmp_path / "rows.csv")
    assert run("voxel_advice.py", "--table", tmp_path / "rows.csv", cwd=tmp_path) == tables


def test_voxel_advice_by_trial(suites, tmp_path):
    out = tmp_path / "out"
    printed = run("voxel_advice.py", "--suites", suites, "--groups", "full", "--limit", 1,
                  "--trial", "--out", out, cwd=tmp_path)
    rows = read_csv(out / "rows.csv")
    assert [r["choice"] for r in rows] == ["hand", "suggested", "trial"]
    factors = [float(rows[2]["voxel_m"]) / float(rows[1]["voxel_m"])]
    assert factors[0] == pytest.approx(min(VOXEL_LADDER,
                                           key=lambda f: abs(f - factors[0])))
    assert "trial success" in printed.splitlines()[2]
    assert len(rows[0]["tried"].split(";")) == 1
    assert len(rows[2]["tried"].split(";")) in (2, len(VOXEL_LADDER))
