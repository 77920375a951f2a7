"""``o3d-spectral eval`` ends with the report's summary: success and median time per suite
and method, aligned for a terminal or a log."""

import pytest

from o3d_spectral.cli import main
from o3d_spectral.harness.records import load_results
from o3d_spectral.harness.report import run_summary
from tests.conftest import full_suite

pytest.importorskip("pandas")


@pytest.fixture(scope="module")
def suite_dir(tmp_path_factory):
    return full_suite(tmp_path_factory, 2)


def test_eval_prints_the_summary_before_its_last_line(suite_dir, tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["-q", "eval", "--suite", str(suite_dir), "--methods", "icp_point_to_point",
                 "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    lines = printed.strip().splitlines()
    table = [line for line in lines if line.startswith("|")]
    assert lines[-1].startswith(f"wrote {out}") and printed.startswith(table[0])
    assert table[0].split("|")[1:-1] == [
        " suite      ", " method             ", "   n ", " success (%) ",
        " median time (s) ", " failed "]
    assert len({len(line) for line in table}) == 1  # columns aligned
    frame = load_results(out)
    row = table[2].split("|")
    assert row[1].strip() == "C-1 (full)" and row[2].strip() == "icp_point_to_point"
    assert float(row[4]) == pytest.approx(100 * frame["success"].mean(), abs=0.05)
    assert float(row[5]) == pytest.approx(frame["time_s"].median(), abs=5e-4)
    assert run_summary(out) == "\n".join(table) + "\n"


def test_eval_of_a_shard_with_nothing_to_run_prints_no_table(suite_dir, tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["-q", "eval", "--suite", str(suite_dir), "--methods", "icp_point_to_point",
                 "--shard", "0/50", "--out", str(out)]) == 0
    assert capsys.readouterr().out.startswith(f"wrote {out}")
