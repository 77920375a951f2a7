"""Runs stopped or crowded: SIGTERM and Ctrl-C at any moment, closed and broken standard
streams, two runs into one output folder."""

from __future__ import annotations

import json
import logging
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

import o3d_spectral
from o3d_spectral.cli import build_parser, main
from o3d_spectral.io.folder_lock import CLAIMS, LOCK, FolderBusyError, folder_lock

ROOT = Path(o3d_spectral.__file__).resolve().parents[1]

#: A method slow enough for a second run to find the first still going.
SLOW_PLUGIN = """
import time

import numpy as np

from o3d_spectral.harness.methods import register_method


@register_method("slow_identity")
def slow_identity(source, target, voxel_size, seed):
    time.sleep(float(__import__("os").environ.get("SLOW_SECONDS", "3")))
    return np.eye(4), {}
"""


def _env(tmp_path: Path, seconds: float = 3.0) -> dict:
    (tmp_path / "plugins").mkdir(exist_ok=True)
    (tmp_path / "plugins" / "slow_plugin.py").write_text(SLOW_PLUGIN)
    path = [str(ROOT), str(tmp_path / "plugins"), os.environ.get("PYTHONPATH", "")]
    return os.environ | {"PYTHONPATH": os.pathsep.join(path), "SLOW_SECONDS": str(seconds)}


def _start(*args: str, env: dict | None = None, **kwargs) -> subprocess.Popen:
    """``o3d-spectral ARGS`` as the installed script runs it."""
    code = "from o3d_spectral.cli import program; program()"
    return subprocess.Popen([sys.executable, "-c", code, *args], env=env or _env_plain(),
                            stdout=kwargs.pop("stdout", subprocess.PIPE),
                            stderr=subprocess.PIPE, text=True, **kwargs)


def _env_plain() -> dict:
    return os.environ | {"PYTHONPATH": os.pathsep.join([str(ROOT),
                                                        os.environ.get("PYTHONPATH", "")])}


def _no_lock_left(folder: Path) -> None:
    assert not (folder / LOCK).exists() and not (folder / CLAIMS).exists()


# ------------------------------------------------------------------------ folder locks


def test_a_claimed_folder_refuses_a_second_run_naming_the_first(tmp_path):
    with folder_lock(tmp_path, "o3d-spectral first"):
        busy = rf"{tmp_path} is in use by another run: o3d-spectral first \(process {os.getpid()}\)"
        with pytest.raises(FolderBusyError, match=busy), folder_lock(tmp_path, "second"):
            pass
    _no_lock_left(tmp_path)
    with folder_lock(tmp_path, "third"):  # free again
        pass


def test_only_the_parts_of_one_group_share_a_folder(tmp_path):
    with folder_lock(tmp_path, "eval", group="run", part="0/2"):
        with folder_lock(tmp_path, "eval", group="run", part="1/2"):
            for group, part in (("run", "0/2"), ("other", "1/2"), (None, None)):
                with pytest.raises(FolderBusyError), folder_lock(tmp_path, "eval", group=group,
                                                                 part=part):
                    pass
    _no_lock_left(tmp_path)


def test_a_stale_claim_is_taken_over_with_a_note(tmp_path, caplog):
    (tmp_path / CLAIMS).mkdir()
    (tmp_path / CLAIMS / "123-dead.json").write_text(json.dumps(
        {"command": "o3d-spectral eval", "pid": 123, "group": None, "part": None}))
    with caplog.at_level(logging.WARNING), folder_lock(tmp_path, "eval"):
        pass
    assert "took over the claim of o3d-spectral eval (process 123)" in caplog.text
    _no_lock_left(tmp_path)


def test_a_folder_made_for_a_run_that_wrote_nothing_is_removed(tmp_path):
    with folder_lock(tmp_path / "new", "eval"):
        assert (tmp_path / "new").is_dir()
    assert not (tmp_path / "new").exists()
    with folder_lock(tmp_path, "eval"):
        (tmp_path / "kept.txt").write_text("x")
    assert (tmp_path / "kept.txt").exists()


@pytest.mark.slow
def test_two_evals_started_together_into_one_folder_one_is_refused(tmp_path):
    suite, out = tmp_path / "suite", tmp_path / "run"
    o3d_spectral.synthetic.make_suite("full", 1, 0, suite, progress=False)
    env = _env(tmp_path)
    command = ["eval", "--suite", str(suite), "--out", str(out), "--plugin", "slow_plugin",
               "--methods", "slow_identity"]
    runs = [_start(*command, env=env) for _ in range(2)]
    done = [run.communicate(timeout=300) for run in runs]
    codes = [run.returncode for run in runs]
    assert sorted(codes) == [0, 1], done
    refused, clean = (1, 0) if codes[1] == 1 else (0, 1)
    assert done[refused][1].strip().splitlines() == [
        f"o3d-spectral eval: error: {out} is in use by another run: o3d-spectral eval "
        f"(process {runs[clean].pid}); wait for it to end or choose another folder"]
    rows = [line for path in (out / "results").glob("*.jsonl")
            for line in path.read_text().splitlines()]
    assert len(rows) == 1  # one instance, one method: once
    _no_lock_left(out)


@pytest.mark.slow
def test_the_shards_of_one_run_write_one_folder_at_once(tmp_path):
    suite, out = tmp_path / "suite", tmp_path / "run"
    o3d_spectral.synthetic.make_suite("full", 2, 0, suite, progress=False)
    env = _env(tmp_path, seconds=2.0)
    command = ["eval", "--suite", str(suite), "--out", str(out), "--plugin", "slow_plugin",
               "--methods", "slow_identity", "--shard"]
    runs = [_start(*command, shard, env=env) for shard in ("0/2", "1/2")]
    errors = [run.communicate(timeout=300)[1] for run in runs]
    assert [run.returncode for run in runs] == [0, 0], errors
    rows = [json.loads(line) for path in (out / "results").glob("*.jsonl")
            for line in path.read_text().splitlines()]
    assert sorted(row["index"] for row in rows) == [0, 1]
    _no_lock_left(out)


# ------------------------------------------------------------------------------ signals


def _command_function(argv: list[str]):
    """The module and attribute name of the function the command line ``argv`` runs."""
    func = build_parser().parse_args(argv).func
    return sys.modules[func.__module__], func.__name__


ARGUMENTS = {
    "register": ["a.ply", "b.ply", "--voxel-size", "0.01"],
    "demo": [], "make-suite": ["full", "--out", "{tmp}/s"],
    "eval": ["--suite", "{tmp}/s", "--out", "{tmp}/r"],
    "report": ["{tmp}/r", "--out", "{tmp}/p"], "convert": ["dragon", "{tmp}/c"], "servo": [],
    "reconstruct": ["a.ply", "b.ply", "--voxel-size", "0.01", "--out", "{tmp}/o"],
}


@pytest.mark.parametrize("command", sorted(ARGUMENTS))
@pytest.mark.parametrize("number, word, status", [(signal.SIGTERM, "terminated", 143),
                                                  (signal.SIGINT, "interrupted", 130)])
def test_a_signal_in_any_command_is_one_line_and_its_status(command, number, word, status,
                                                            tmp_path, monkeypatch, capsys):
    argv = [command, *(a.replace("{tmp}", str(tmp_path)) for a in ARGUMENTS[command])]
    module, name = _command_function(argv)

    def signalled(args):
        os.kill(os.getpid(), number)  # delivered to this (the main) thread
        time.sleep(5.0)  # interrupted by the handler long before
        raise AssertionError("the signal did not stop the command")

    monkeypatch.setattr(module, name, signalled)
    assert main(argv) == status
    assert capsys.readouterr().err.strip().splitlines()[-1] == f"o3d-spectral {command}: {word}"
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL  # restored


@pytest.mark.slow
@pytest.mark.parametrize("number, status", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_a_signal_at_any_moment_of_a_run_is_one_line(number, status, tmp_path):
    """From the first instructions of the program (imports of Open3D and NumPy included)
    to the end: one line, no traceback, the stop's status."""
    for moment in (0.3, 0.6, 1.0, 2.0):
        out = tmp_path / f"s{moment}"
        run = _start("make-suite", "full", "--n", "400", "--out", str(out))
        time.sleep(moment)
        run.send_signal(number)
        _, stderr = run.communicate(timeout=120)
        lines = [line for line in stderr.splitlines() if "WARNING" not in line]
        assert run.returncode == status, (moment, stderr)
        assert len(lines) == 1 and lines[0].endswith(("terminated", "interrupted")), stderr


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_a_terminated_eval_keeps_its_rows_and_releases_its_folder(tmp_path):
    suite, out = tmp_path / "suite", tmp_path / "run"
    o3d_spectral.synthetic.make_suite("full", 3, 0, suite, progress=False)
    run = _start("eval", "--suite", str(suite), "--out", str(out), "--plugin", "slow_plugin",
                 "--methods", "icp_point_to_point", "slow_identity", env=_env(tmp_path, 300))
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and not any(
            path.stat().st_size for path in (out / "results").glob("*.jsonl")):
        time.sleep(0.1)
    run.terminate()  # SIGTERM, to the parent alone
    _, stderr = run.communicate(timeout=60)
    assert run.returncode == 143
    assert stderr.strip().splitlines() == [
        f"o3d-spectral eval: terminated; the rows done so far stay in {out} (run the same "
        "command again to resume)"]
    assert any(path.stat().st_size for path in (out / "results").glob("*.jsonl"))
    _no_lock_left(out)


# ----------------------------------------------------------------------------- streams


@pytest.mark.parametrize("argv", [["--version"], ["--help"], ["register", "--help"]])
def test_a_reader_that_goes_away_ends_the_program_quietly(argv):
    run = _start(*argv)
    run.stdout.close()  # before the program writes: its write meets a broken pipe
    _, stderr = run.communicate(timeout=60)
    assert run.returncode == 141 and not stderr.strip()


def test_a_closed_standard_output_is_one_line_and_status_1():
    run = _start("--version", stdout=subprocess.DEVNULL, preexec_fn=lambda: os.close(1))
    _, stderr = run.communicate(timeout=60)
    assert run.returncode == 1
    assert stderr.strip().splitlines() == [
        "o3d-spectral: error: the standard output is closed: nowhere to write the results "
        "(redirect it to a file or to /dev/null)"]
