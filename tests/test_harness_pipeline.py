"""A two-instance suite end to end through ``eval`` and ``report``; resuming; workers."""

import pytest

pytest.importorskip("pandas", reason="the harness extra is not installed")
pytest.importorskip("matplotlib", reason="the harness extra is not installed")
from pandas.testing import assert_frame_equal  # noqa: E402

from o3d_spectral.cli import main
from o3d_spectral.harness import load_results, method_names, method_settings, run_eval
from o3d_spectral.harness.records import TABLE_FILE, read_config, result_files
from o3d_spectral.synthetic.suite import make_suite
from tests.conftest import full_suite
from tests.latex import compile_tables, needs_latex

VOLATILE = {"time_s"}  # the only column allowed to differ between identical runs


@pytest.fixture(scope="module")
def suite_dir(tmp_path_factory):
    return full_suite(tmp_path_factory, 2)


@pytest.fixture(scope="module")
def run_dir(suite_dir, tmp_path_factory):
    """Every registered method on both instances, through the command line."""
    out = tmp_path_factory.mktemp("run")
    assert main(["eval", "--suite", str(suite_dir), "--out", str(out), "--quiet"]) == 0
    return out


def _lines(run):
    """The complete rows of every session's results file."""
    texts = [file.read_text() for file in result_files(run)]
    return [line for text in texts for line in text[: text.rfind("\n") + 1].splitlines()]


def assert_same_rows(a, b):
    """Equal apart from the volatile columns (NaN equal to NaN)."""
    assert_frame_equal(
        a.drop(columns=sorted(VOLATILE)).reset_index(drop=True),
        b.drop(columns=sorted(VOLATILE)).reset_index(drop=True),
    )


@pytest.mark.slow
def test_eval_writes_one_row_per_instance_and_method(run_dir):
    frame = load_results(run_dir)
    # A tuned method skips the tuning split (instance 0 of 2).
    tuned = [m for m in method_names() if "tuning_split" in method_settings(m)]
    assert len(frame) == 2 * len(method_names()) - len(tuned)
    assert set(frame["method"]) == set(method_names())
    assert frame["error"].isna().all()
    table = (run_dir / TABLE_FILE).read_text().splitlines()
    assert len(table) == 1 + len(frame)
    for column in (
        "rotation_error_sym_deg",
        "translation_error_sym_m",
        "success",
        "time_s",
        "squared_rotation_error_rad2",
        "fitness",
        "inlier_rmse",
        "iterations",
    ):
        assert column in table[0]
    spectral = frame[frame["method"] == "spectral"]
    assert (spectral["curve_rotation_deg"].map(len) == spectral["iterations"]).all()
    assert spectral["rotation_gradient_norm_rad"].notna().all()
    config = read_config(run_dir)
    assert config["sessions"][0]["registrations"] == len(frame)


@pytest.mark.slow
def test_config_records_the_commit_versions_and_method_settings(suite_dir, tmp_path):
    chosen = ["icp_point_to_point", "fgr"]
    run_eval([suite_dir], tmp_path, methods=chosen, limit=1, progress=False)
    run_eval([suite_dir], tmp_path, methods=["fpfh_ransac"], limit=1, progress=False)
    sessions = read_config(tmp_path)["sessions"]
    assert len(sessions) == 2
    for session, methods in zip(sessions, [chosen, ["fpfh_ransac"]], strict=True):
        assert "commit" in session
        assert session["commit"] is None or len(session["commit"]) == 40
        assert set(session["versions"]) == {
            "o3d_spectral",
            "open3d",
            "numpy",
            "scipy",
            "pyfftw",
            "python",
        }
        assert all(isinstance(v, str) for v in session["versions"].values())
        assert session["method_settings"] == {m: method_settings(m) for m in methods}
    assert sessions[0]["method_settings"]["fgr"]["fgr"]["maximum_correspondence_distance_voxels"]


@pytest.mark.slow
def test_report_writes_every_table_and_plot(run_dir, tmp_path):
    out = tmp_path / "report"
    assert main(["report", str(run_dir), "--out", str(out)]) == 0
    tables = [
        f"{name}.{ext}"
        for name in ("table1", "summary", "comparison")
        for ext in ("md", "tex", "csv")
    ]
    plots = ["success_vs_angle.png", "cumulative_errors.png", "time.png"]
    plots += [f"convergence_{m}.png" for m in method_names() if m.startswith("spectral")]
    for name in [*tables, *plots, "report.md"]:
        assert (out / name).stat().st_size > 0, name
    for name in plots:
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    table1 = (out / "table1.tex").read_text()
    assert r"\toprule" in table1 and r"\bottomrule" in table1 and "C-1 (full)" in table1
    assert "rad$^2$" in table1
    report = (out / "report.md").read_text()
    assert "](table1" not in report and "![Time per registration](time.png)" in report


@needs_latex
@pytest.mark.slow
def test_every_report_table_compiles_with_pdflatex(run_dir, tmp_path):
    assert main(["report", str(run_dir), "--out", str(tmp_path / "report")]) == 0
    tables = sorted((tmp_path / "report").glob("*.tex"))
    text = " ".join(compile_tables([p.read_text() for p in tables], tmp_path / "tex").split())
    for method in method_names():
        assert method in text, method


@pytest.mark.slow
def test_resume_skips_done_pairs_and_reruns_identically(suite_dir, run_dir):
    lines = _lines(run_dir)
    before = load_results(run_dir)
    # Interrupted: two rows missing and a third cut off halfway through.
    (file,) = result_files(run_dir)
    file.write_text("\n".join(lines[:-3]) + "\n" + lines[-3][:40])
    run_eval([suite_dir], run_dir, progress=False)
    assert len(_lines(run_dir)) == len(lines)
    assert_same_rows(load_results(run_dir), before)
    run_eval([suite_dir], run_dir, progress=False)
    assert len(_lines(run_dir)) == len(lines)
    sessions = read_config(run_dir)["sessions"]
    assert [s["registrations"] for s in sessions] == [len(lines), 3, 0]


@pytest.mark.slow
def test_two_workers_give_the_same_rows(suite_dir, run_dir, tmp_path):
    chosen = ["icp_point_to_plane", "fpfh_ransac", "spectral"]
    run_eval([suite_dir], tmp_path, methods=chosen, workers=2, limit=1, progress=False)
    two = load_results(tmp_path)
    one = load_results(run_dir)
    one = one[one["method"].isin(chosen) & (one["index"] == 0)]
    assert len(two) == 3
    assert_same_rows(two, one)


@pytest.mark.slow
def test_resume_refuses_other_settings(suite_dir, run_dir, tmp_path):
    with pytest.raises(ValueError, match="voxel_size"):
        run_eval([suite_dir], run_dir, voxel_size=0.01, progress=False)
    other = tmp_path / "full"  # same folder name, another seed
    make_suite("full", 1, 1, other, progress=False)
    with pytest.raises(ValueError, match="seed 1"):
        run_eval([other], run_dir, progress=False)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"workers": 0}, "workers"),
        ({"voxel_size": -1.0}, "voxel_size"),
        ({"limit": 0}, "limit"),
        ({"methods": ["nope"]}, "nope"),
    ],
)
def test_eval_rejects_bad_arguments(suite_dir, tmp_path, kwargs, name):
    with pytest.raises(ValueError, match=name):
        run_eval([suite_dir], tmp_path, progress=False, **kwargs)


@pytest.mark.slow
def test_open3d_methods_repeat_bit_for_bit(suite_dir, tmp_path):
    # Open3D sums on several threads in a different order each run; the workers use one.
    chosen = ["icp_point_to_plane", "fpfh_ransac", "fgr", "spectral_global"]
    runs = []
    for name in ("a", "b"):
        run_eval([suite_dir], tmp_path / name, methods=chosen, progress=False)
        runs.append(load_results(tmp_path / name).sort_values(["index", "method"]))
    first, second = (list(run["transformation"]) for run in runs)
    assert first == second
