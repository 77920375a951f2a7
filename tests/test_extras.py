"""Without an optional extra, the core install still runs the demo, and every command that
needs the extra stops before it starts with one line naming it (exit code 1).

A missing module is simulated by ``sys.modules[name] = None``: its import then raises
``ModuleNotFoundError`` and ``importlib.util.find_spec`` finds nothing, as when it is not
installed.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from o3d_spectral.cli import main
from o3d_spectral.common import extras

ROOT = Path(__file__).resolve().parents[1]


def hide(monkeypatch: pytest.MonkeyPatch, *modules: str) -> None:
    """Make ``modules`` (and their submodules already imported) look uninstalled."""
    for name in list(sys.modules):
        if name.partition(".")[0] in modules:
            monkeypatch.delitem(sys.modules, name)
    for module in modules:
        monkeypatch.setitem(sys.modules, module, None)


def one_error_line(capsys: pytest.CaptureFixture) -> str:
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1, err
    assert "Traceback" not in err and "-vv" not in err
    return err.strip()


def test_the_extras_named_are_the_packages_extras():
    tomllib = pytest.importorskip("tomllib", reason="tomllib is in Python 3.11 and later")
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert set(extras.EXTRAS) <= set(pyproject["project"]["optional-dependencies"])
    assert extras.extra_of("matplotlib.pyplot") == "harness"
    assert extras.extra_of("dask.distributed") == "cluster"
    assert extras.extra_of("numpy") is None


def test_require_names_the_extra(monkeypatch):
    hide(monkeypatch, "tqdm", "pybullet")
    with pytest.raises(extras.MissingExtraError) as caught:
        extras.require("tqdm", "the progress bar")
    assert isinstance(caught.value, ImportError) and caught.value.extra == "harness"
    assert str(caught.value) == ("the progress bar needs the 'harness' extra (tqdm is missing): "
                                 "pip install 'o3d-spectral[harness]'")
    from o3d_spectral.servo import robot

    with pytest.raises(ImportError, match=r"'servo' extra .*o3d-spectral\[servo\]"):
        robot.load_pybullet()


def test_make_suite_without_the_harness_extra_says_which(monkeypatch, capsys, tmp_path):
    hide(monkeypatch, "tqdm")
    out = tmp_path / "suite"
    assert main(["make-suite", "partial", "--n", "1", "--out", str(out)]) == 1
    assert one_error_line(capsys) == (
        "o3d-spectral make-suite: error: this command needs the 'harness' extra "
        "(tqdm is missing): pip install 'o3d-spectral[harness]'"
    )
    assert not out.exists()  # stopped before it started


@pytest.mark.parametrize(
    ("argv", "hidden", "extra"),
    [
        (["show-suite", "suite", "--out", "x.png"], "matplotlib", "harness"),
        (["eval", "--suite", "suite", "--out", "run"], "pandas", "harness"),
        (["eval", "--suite", "suite", "--out", "run", "--cluster", "local"], "distributed",
         "cluster"),
        (["report", "run", "--out", "report"], "pandas", "harness"),
        (["servo", "--out", "servo"], "pybullet", "servo"),
    ],
    ids=["show-suite", "eval", "eval-cluster", "report", "servo"],
)
def test_every_command_names_the_extra_it_needs(monkeypatch, capsys, tmp_path, argv, hidden,
                                                extra):
    monkeypatch.chdir(tmp_path)
    hide(monkeypatch, hidden)
    assert main(argv) == 1
    line = one_error_line(capsys)
    assert line.startswith(f"o3d-spectral {argv[0]}: error: ")
    assert line.endswith(f"needs the '{extra}' extra ({hidden} is missing): "
                         f"pip install 'o3d-spectral[{extra}]'")
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # nothing written


def test_an_unchecked_import_of_an_extra_is_one_line_too(monkeypatch, capsys):
    from o3d_spectral.cli import report

    def needs_pandas(args):
        raise ModuleNotFoundError("No module named 'pandas'", name="pandas")

    monkeypatch.setattr(report, "report_command", needs_pandas)
    assert main(["report", "run", "--out", "report"]) == 1
    assert one_error_line(capsys) == (
        "o3d-spectral report: error: this command needs the 'harness' extra "
        "(pandas is missing): pip install 'o3d-spectral[harness]'"
    )


def test_demo_without_matplotlib_prints_the_numbers_and_a_hint(monkeypatch, capsys, tmp_path):
    hide(monkeypatch, "matplotlib")
    assert main(["demo", "--object", "cracker_box", "--seed", "1", "--out", str(tmp_path)]) == 0
    out, err = capsys.readouterr()
    assert "rotation error" in out and f"wrote {tmp_path / 'result.json'}" in out
    assert err.splitlines() == [  # a box: its half turn fits as well, said first
        "o3d-spectral: WARNING: ambiguous: a pose 180 deg away fits as well (a symmetric "
        "object?): result.ambiguity, result.ambiguous_transformation",
        "o3d-spectral: WARNING: no convergence plot: plotting needs the 'harness' extra "
        "(matplotlib is missing): pip install 'o3d-spectral[harness]'"
    ]
    assert not (tmp_path / "convergence.png").exists()
    result = json.loads((tmp_path / "result.json").read_text())
    assert result["convergence_plot"] is None and result["rotation_error_deg"] < 5.0
