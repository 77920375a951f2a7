"""What the command line writes where: results alone on stdout (one JSON document with
``--json``, whatever the verbosity and whatever Open3D logs), progress on stderr, a status
line on a terminal only; its options' help and the checks made before any work."""

import argparse
import io
import json
import logging
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import open3d as o3d
import pytest

import o3d_spectral.cli as cli
from o3d_spectral.cli import _output, build_parser, main
from tests.conftest import sample_model

REPO = Path(__file__).resolve().parents[1]


def _cli(*argv: str) -> subprocess.CompletedProcess:
    """``o3d-spectral ARGV`` in a fresh process, its stdout and stderr piped apart."""
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    return subprocess.run([sys.executable, "-m", "o3d_spectral.cli", *argv],
                          capture_output=True, text=True, env=env, timeout=300)


@pytest.fixture(scope="module")
def pair(tmp_path_factory) -> tuple[Path, Path]:
    """A model and its copy moved by 2 cm, as PLY files."""
    folder = tmp_path_factory.mktemp("pair")
    source = sample_model("mustard_bottle", 3000)
    T = np.eye(4)
    T[:3, 3] = [0.02, 0.0, -0.01]
    o3d.io.write_point_cloud(str(folder / "source.ply"), source)
    o3d.io.write_point_cloud(str(folder / "target.ply"),
                             o3d.geometry.PointCloud(source).transform(T))
    return folder / "source.ply", folder / "target.ply"


def _partly_readable(folder: Path) -> Path:
    """A PLY whose header is sound but whose data Open3D fails to parse (it returns the
    points read so far and only prints a warning)."""
    path = folder / "partial.ply"
    path.write_text("ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\n"
                    "property float y\nproperty float z\nend_header\n0 0 0\n1 2 abc\n")
    return path


@pytest.mark.slow
def test_json_is_the_only_thing_on_stdout_even_with_debug_logging(pair):
    """-vv: Open3D's debug log and the package's progress go to stderr; stdout parses
    as one JSON document. In a pipe, no status line or progress frame is drawn."""
    done = _cli("-vv", "register", str(pair[0]), str(pair[1]), "--voxel-size", "0.008",
                "--json")
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout)  # the whole of stdout, nothing before or after
    np.testing.assert_allclose(np.array(summary["transformation"])[:3, 3], [0.02, 0, -0.01],
                               atol=2e-3)
    assert "[Open3D DEBUG]" in done.stderr  # Open3D did log: it went to stderr
    assert "o3d-spectral: INFO: registering" in done.stderr
    assert "\r" not in done.stderr and "\x1b[K" not in done.stderr


@pytest.mark.slow
def test_a_failed_read_leaves_stdout_empty(tmp_path, pair):
    """Open3D's warning about a file it reads only in part goes to stderr, and becomes the
    error (exit 1) naming the file, rather than a registration of what it read."""
    bad = _partly_readable(tmp_path)
    for verbosity in ([], ["-vv"], ["-q"]):
        done = _cli(*verbosity, "register", str(bad), str(pair[1]), "--voxel-size", "0.008",
                    "--json")
        assert done.returncode == 1 and done.stdout == "", (verbosity, done.stdout)
        last = done.stderr.splitlines()[-1]
        assert last.startswith(f"o3d-spectral register: error: {bad}: Open3D read it only "
                               "in part (Read PLY failed"), last


@pytest.mark.parametrize("case", ["missing", "empty", "partial", "nan_init", "save_folder"])
def test_every_failure_leaves_stdout_empty_and_exits_1(tmp_path, pair, capfd, case):
    """In one process too (descriptor-level capture): each failure exits 1 with stdout
    empty, with or without --json and -vv."""
    source, target = map(str, pair)
    extra: list[str] = []
    if case == "missing":
        source = str(tmp_path / "missing.ply")
    elif case == "empty":
        source = str(tmp_path / "empty.ply")
        Path(source).write_text("ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\n"
                                "property float y\nproperty float z\nend_header\n")
    elif case == "partial":
        source = str(_partly_readable(tmp_path))
    elif case == "nan_init":
        init = np.eye(4)
        init[1, 2] = np.nan
        np.savetxt(tmp_path / "init.txt", init)
        extra = ["--init", str(tmp_path / "init.txt")]
    else:
        extra = ["--save", str(tmp_path / "no" / "such" / "moved.ply")]
    for flags in ([], ["--json"]):
        for verbosity in ([], ["-vv"]):
            code = main([*verbosity, "register", source, target, "--voxel-size", "0.008",
                         *extra, *flags])
            out, err = capfd.readouterr()
            assert code == 1 and out == "", (flags, verbosity, out)
            assert "o3d-spectral register: error:" in err


def test_nan_init_names_the_entries_not_the_shape(tmp_path, pair, capsys):
    init = np.eye(4)
    init[1, 2] = np.nan
    init[3, 0] = np.inf
    np.savetxt(tmp_path / "init.txt", init)
    argv = ["register", *map(str, pair), "--voxel-size", "0.008"]
    assert main([*argv, "--init", str(tmp_path / "init.txt")]) == 1
    err = capsys.readouterr().err
    assert "2 of its 16 numbers are not finite" in err
    assert "row 2 column 3, row 4 column 1" in err and "shape" not in err
    np.savetxt(tmp_path / "short.txt", np.eye(4)[:3])
    assert main([*argv, "--init", str(tmp_path / "short.txt")]) == 1
    assert "not a 4x4 matrix: 3 rows of 4 numbers" in capsys.readouterr().err


def test_save_is_checked_before_the_clouds_are_read(tmp_path, pair, capsys):
    """A --save FILE Open3D could not write is refused before any work: no cloud read (no
    INFO line), exit 1 for a missing folder, 2 for an extension Open3D does not write."""
    argv = ["-v", "register", *map(str, pair), "--voxel-size", "0.008", "--save"]
    (tmp_path / "file.txt").write_text("")
    for save, code, message in [
        (tmp_path / "no" / "moved.ply", 1, "no such folder"),
        (tmp_path / "file.txt" / "moved.ply", 1, "no such folder"),
        (tmp_path, 2, "not no extension"),
        (tmp_path / "moved.obj", 2, "not .obj"),
    ]:
        start = time.perf_counter()
        assert main([*argv, str(save)]) == code, save
        err = capsys.readouterr().err
        assert message in err and "INFO: read" not in err, err
        assert time.perf_counter() - start < 5.0  # nothing registered


def test_register_v_shows_progress_lines_as_they_happen(pair, capsys):
    """-v: INFO records of the o3d_spectral loggers on stderr, the reading, registration
    and command lines among them in order; stdout unchanged."""
    assert main(["-v", "register", *map(str, pair), "--voxel-size", "0.008"]) == 0
    out, err = capsys.readouterr()
    assert np.loadtxt(out.splitlines()[:4]).shape == (4, 4)
    lines = [line for line in err.splitlines() if line.startswith("o3d-spectral: INFO: ")]
    steps = ["read " + str(pair[0]), "read " + str(pair[1]), "registering source.ply onto "
             "target.ply", "registered in", "register done in"]
    where = [next(i for i, line in enumerate(lines) if step in line) for step in steps]
    assert where == sorted(where), lines


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_status_line_on_a_terminal_follows_the_log(monkeypatch):
    """On a terminal, after STATUS_DELAY, a line shows the time and the latest INFO
    message of any o3d_spectral logger, even when INFO is not printed; it is erased
    before a log line and at the end."""
    terminal = _Terminal()
    monkeypatch.setattr(sys, "stderr", terminal)
    monkeypatch.setattr(_output, "STATUS_DELAY", 0.05)
    monkeypatch.setattr(_output, "STATUS_INTERVAL", 0.02)
    stage = logging.getLogger("o3d_spectral.registration")
    with _output.package_logging(logging.WARNING, "o3d-spectral register"):
        stage.info("stage %s: %.3f s", "sweep", 1.25)
        time.sleep(0.3)
        stage.warning("something to say")
        time.sleep(0.1)
    text = terminal.getvalue()
    assert "\ro3d-spectral register: 0 s; stage sweep: 1.250 s\x1b[K" in text
    assert "INFO" not in text  # WARNING level: shown on the status line only
    assert "\r\x1b[Ko3d-spectral: WARNING: something to say\n" in text
    assert text.endswith("\r\x1b[K")


def test_status_line_only_on_a_terminal_and_not_with_q(monkeypatch):
    args = build_parser().parse_args(["register", "a.ply", "b.ply", "--voxel-size", "0.01"])
    monkeypatch.setattr(sys, "stderr", io.StringIO())
    assert cli.status_label(args) is None and not cli.show_progress(args)
    monkeypatch.setattr(sys, "stderr", _Terminal())
    assert cli.status_label(args) == "o3d-spectral register" and cli.show_progress(args)
    args.errors_only = True
    assert cli.status_label(args) is None and not cli.show_progress(args)


def _commands() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    subparsers = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(subparsers.choices)


def test_every_option_has_help_and_shows_its_default():
    for name, command in _commands().items():
        text = command.format_help()
        for action in command._actions:
            if not action.option_strings or action.help == argparse.SUPPRESS:
                continue
            assert action.help, f"{name} {action.option_strings[0]} has no help"
            default = action.default
            if not (default is None or default is False or default == []
                    or default is argparse.SUPPRESS):
                assert "default" in action.help or f"(default: {default})" in " ".join(
                    text.split()), f"{name} {action.option_strings[0]}: default not shown"
    register = " ".join(_commands()["register"].format_help().split())
    assert "most iterations of the law" in register and "(default: 100)" in register
    demo = " ".join(_commands()["demo"].format_help().split())
    assert "--seed SEED seed of the random rotation" in demo and "(default: 0)" in demo


def test_demo_object_lists_the_bundled_models(capsys):
    from o3d_spectral.synthetic.models import model_names

    demo = " ".join(_commands()["demo"].format_help().split())
    assert "bundled model: " + ", ".join(model_names()) in demo
    assert main(["demo", "--object", "teapot"]) == 2
    assert "--object must be one of banana, " in capsys.readouterr().err


def test_progress_options_are_the_global_ones():
    """eval and make-suite have no --quiet of their own in --help (the global -q hides
    progress); given after the command it is still taken, as -q."""
    for name in ("eval", "make-suite"):
        assert "--quiet" not in _commands()[name].format_help()
    args = build_parser().parse_args(["eval", "--suite", "s", "--out", "o", "--quiet"])
    assert args.errors_only
    args = build_parser().parse_args(["-q", "eval", "--suite", "s", "--out", "o"])
    assert args.errors_only


def test_make_suite_draws_no_progress_frames_in_a_pipe(tmp_path, capsys):
    assert main(["make-suite", "full", "--n", "2", "--out", str(tmp_path / "s")]) == 0
    out, err = capsys.readouterr()
    assert out.startswith("wrote 2 full instances") and "\r" not in err and "inst" not in err


def test_make_suite_refuses_a_file_as_its_folder(tmp_path, capsys):
    """--out naming an existing file is a usage error (exit 2), one line naming --out,
    and the file is left as it was."""
    taken = tmp_path / "taken.txt"
    taken.write_text("kept\n")
    assert main(["make-suite", "full", "--n", "1", "--out", str(taken)]) == 2
    err = capsys.readouterr().err
    assert err == f"o3d-spectral make-suite: error: --out {taken}: a file, not a folder\n"
    assert taken.read_text() == "kept\n"
