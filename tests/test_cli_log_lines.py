"""The command line's log records and Open3D's messages never share a line of stderr, and
a whole ``register -vv`` run's stderr is made of whole lines of either."""

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import open3d as o3d

from tests.conftest import sample_model

REPO = Path(__file__).resolve().parents[1]
ENV = {**os.environ, "PYTHONPATH": str(REPO)}
PREFIXES = ("[Open3D ", "o3d-spectral: ")

#: Open3D's Python module prints a message, then its newline, in two writes (from any
#: thread): a record logged in between, and Open3D's own messages from threads at work.
SCRIPT = textwrap.dedent("""
    import logging, sys, threading
    import numpy as np
    import open3d as o3d
    from o3d_spectral.cli._output import logging_to_stderr, results, stdout_for_results_only

    log = logging.getLogger("o3d_spectral.test")
    points = np.random.default_rng(0).random((50, 3))
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    half, logged = threading.Event(), threading.Event()

    def open3d_message():
        sys.stdout.write("[Open3D DEBUG] ICP Iteration #0: Fitness 1.0000, RMSE 0.0048")
        half.set()
        logged.wait()
        sys.stdout.write("\\n")

    def open3d_debug():
        for _ in range(200):
            cloud.voxel_down_sample(0.1)

    with stdout_for_results_only(), logging_to_stderr(logging.DEBUG):
        thread = threading.Thread(target=open3d_message)
        thread.start()
        half.wait()
        log.warning("low fit 0.42")
        logged.set()
        thread.join()
        workers = [threading.Thread(target=open3d_debug) for _ in range(2)]
        for worker in workers:
            worker.start()
        for k in range(200):
            log.warning("record %d", k)
        for worker in workers:
            worker.join()
        sys.stdout.write("[Open3D DEBUG] unfinished")
        print("result", file=results())
""")


def _whole_lines(text: str) -> list[str]:
    lines = text.splitlines()
    assert text.endswith("\n")
    bad = [line for line in lines
           if not line.startswith(PREFIXES) or any(p in line[1:] for p in PREFIXES)]
    assert not bad, bad[:3]
    return lines


def test_records_and_open3d_messages_never_share_a_line():
    run = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True,
                         env=ENV, timeout=120)
    assert run.returncode == 0, run.stderr
    lines = _whole_lines(run.stderr)
    assert lines[:2] == ["o3d-spectral: WARNING: low fit 0.42",
                         "[Open3D DEBUG] ICP Iteration #0: Fitness 1.0000, RMSE 0.0048"]
    assert len(lines) == 2 + 200 + 2 * 200 + 1 and lines[-1] == "[Open3D DEBUG] unfinished"
    assert run.stdout == "result\n"


def test_register_vv_writes_whole_lines(tmp_path):
    source = sample_model("mustard_bottle", 3000)
    moved = o3d.geometry.PointCloud(source).translate(np.array([0.02, 0.0, -0.01]))
    paths = [tmp_path / "source.ply", tmp_path / "target.ply"]
    for path, cloud in zip(paths, (source, moved), strict=True):
        o3d.io.write_point_cloud(str(path), cloud)
    run = subprocess.run([sys.executable, "-m", "o3d_spectral.cli", "-vv", "register",
                          *map(str, paths), "--voxel-size", "0.008"],
                         capture_output=True, text=True, env=ENV, timeout=300)
    assert run.returncode == 0, run.stderr
    lines = _whole_lines(run.stderr)
    assert any(line.startswith("[Open3D DEBUG]") for line in lines)
