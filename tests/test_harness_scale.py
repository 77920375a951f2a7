"""Evaluation past one process: Dask clusters, shards, older run folders, and the peers
from other packages (two runs into one folder: test_stops.py)."""

import gc
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("pandas", reason="the harness extra is not installed")
pytest.importorskip("matplotlib", reason="the harness extra is not installed")
from pandas.testing import assert_frame_equal  # noqa: E402

import o3d_spectral  # noqa: E402
from o3d_spectral.harness import load_results, run_eval  # noqa: E402
from o3d_spectral.harness.records import (  # noqa: E402
    CONFIG_FILE,
    RESULTS_FILE,
    SESSIONS_DIR,
    read_config,
    result_files,
)
from o3d_spectral.harness.selection import in_shard, parse_shard, selected_indices  # noqa: E402
from tests.conftest import full_suite  # noqa: E402

METHODS = ["icp_point_to_plane", "fpfh_ransac"]
VOLATILE = ["time_s"]  # the only column allowed to differ between identical runs


@pytest.fixture(scope="module")
def suite_dir(tmp_path_factory):
    return full_suite(tmp_path_factory, 4)


@pytest.fixture(scope="module")
def pool_run(suite_dir, tmp_path_factory):
    """Two instances, two methods, on the local process pool (the reference rows)."""
    out = tmp_path_factory.mktemp("pool")
    run_eval([suite_dir], out, methods=METHODS, limit=2, progress=False)
    return load_results(out)


def assert_same_rows(a, b):
    assert_frame_equal(
        a.drop(columns=VOLATILE).reset_index(drop=True),
        b.drop(columns=VOLATILE).reset_index(drop=True),
    )


# ---------------------------------------------------------------------------- Dask


@pytest.mark.slow
def test_local_cluster_gives_the_pool_rows(suite_dir, pool_run, tmp_path):
    pytest.importorskip("dask.distributed", reason="the cluster extra is not installed")
    run_eval(
        [suite_dir], tmp_path, methods=METHODS, limit=2, cluster="local", workers=2,
        progress=False,
    )
    assert_same_rows(load_results(tmp_path), pool_run)
    (session,) = read_config(tmp_path)["sessions"]
    assert session["executor"] == "local" and session["workers"] == 2 and session["complete"]


def _wait_for(path: Path, process: subprocess.Popen, seconds: float) -> None:
    deadline = time.monotonic() + seconds
    while not path.is_file():
        if process.poll() is not None or time.monotonic() > deadline:
            raise RuntimeError(f"the dask scheduler did not start (exit {process.poll()})")
        time.sleep(0.2)


@pytest.mark.slow
def test_scheduler_and_workers_in_other_processes_give_the_pool_rows(
    suite_dir, pool_run, tmp_path
):
    """``dask scheduler`` and ``dask worker`` started as separate processes, reached
    through a scheduler file, as on a cluster."""
    pytest.importorskip("dask.distributed", reason="the cluster extra is not installed")
    dask = shutil.which("dask") or str(Path(sys.executable).with_name("dask"))
    if not Path(dask).exists():
        pytest.skip("the dask command is not installed")
    scheduler_file = tmp_path / "scheduler.json"
    root = str(Path(o3d_spectral.__file__).resolve().parents[1])  # the workers import this copy
    env = os.environ | {"PYTHONPATH": os.pathsep.join([root, os.environ.get("PYTHONPATH", "")])}
    common = ["--scheduler-file", str(scheduler_file)]
    logs = (tmp_path / "dask.log").open("w")
    processes = []
    try:
        processes.append(subprocess.Popen(
            [dask, "scheduler", "--host", "127.0.0.1", "--port", "0",
             "--dashboard-address", ":0", *common],
            env=env, stdout=logs, stderr=subprocess.STDOUT,
        ))
        _wait_for(scheduler_file, processes[0], 60)
        processes.append(subprocess.Popen(
            [dask, "worker", "--nthreads", "1", "--nworkers", "2", "--host", "127.0.0.1",
             "--no-dashboard", *common],
            env=env, stdout=logs, stderr=subprocess.STDOUT,
        ))
        from dask.distributed import Client

        with Client(scheduler_file=str(scheduler_file), timeout=60) as client:
            client.wait_for_workers(2, timeout=120)
        out = tmp_path / "run"
        run_eval(
            [suite_dir], out, methods=METHODS, limit=2, cluster=str(scheduler_file),
            progress=False,
        )
    finally:
        for process in reversed(processes):
            process.terminate()
        for process in reversed(processes):
            try:
                process.wait(timeout=30)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        logs.close()
    assert_same_rows(load_results(out), pool_run)
    assert read_config(out)["sessions"][0]["workers"] == 2


def test_cluster_without_dask_says_how_to_install(monkeypatch, suite_dir, tmp_path):
    import builtins

    real_import = builtins.__import__

    def no_dask(name, *args, **kwargs):
        if name.startswith(("dask", "distributed")):
            raise ImportError(f"no module named {name}")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_dask)
    monkeypatch.delitem(sys.modules, "dask.distributed", raising=False)
    with pytest.raises(ImportError, match=r"o3d-spectral\[cluster\]"):
        run_eval([suite_dir], tmp_path, methods=METHODS, limit=1, cluster="local",
                 progress=False)


# ---------------------------------------------------------------------------- shards


def test_shards_partition_any_selection():
    for count in (1, 2, 3, 5):
        shards = [
            selected_indices(40, condition="partial", suite_seed=3, shard=(i, count))
            for i in range(count)
        ]
        assert sorted(sum(shards, [])) == list(range(40))
    assert in_shard("full", 0, 7, (0, 1))
    assert parse_shard("1/4") == (1, 4)
    for bad in ("4/4", "-1/2", "1", "a/b"):
        with pytest.raises(ValueError, match="shard"):
            parse_shard(bad)


def test_sample_is_seeded_and_independent_of_order():
    first = selected_indices(240, condition="full", suite_seed=0, sample=10, seed=1)
    assert first == selected_indices(240, condition="full", suite_seed=0, sample=10, seed=1)
    assert first != selected_indices(240, condition="full", suite_seed=0, sample=10, seed=2)
    assert len(set(first)) == 10 and first == sorted(first)
    assert selected_indices(5, condition="full", suite_seed=0, limit=3) == [0, 1, 2]


@pytest.mark.slow
def test_two_shards_into_one_folder_give_the_unsharded_rows(suite_dir, pool_run, tmp_path):
    for shard in ("0/2", "1/2"):
        run_eval([suite_dir], tmp_path, methods=METHODS, limit=2, shard=shard, progress=False)
    assert_same_rows(load_results(tmp_path), pool_run)
    config = read_config(tmp_path)
    assert [s["shard"] for s in config["sessions"]] == ["0/2", "1/2"]
    assert len(result_files(tmp_path)) == 2


@pytest.mark.slow
def test_older_run_folders_are_read_and_resumed(suite_dir, tmp_path):
    """A run written before per-session files (config.json, results.jsonl) is merged
    with a new session's files, and resumed without running its pairs again."""
    run_eval([suite_dir], tmp_path, methods=METHODS[:1], limit=1, progress=False)
    (session_file,) = (tmp_path / SESSIONS_DIR).glob("*.json")
    entry = json.loads(session_file.read_text())
    legacy = {key: entry[key] for key in ("voxel_size", "seed", "criteria", "suites", "methods")}
    (tmp_path / CONFIG_FILE).write_text(json.dumps(legacy | {"sessions": [entry["session"]]}))
    (results_file,) = result_files(tmp_path)
    results_file.rename(tmp_path / RESULTS_FILE)
    session_file.unlink()
    run_eval([suite_dir], tmp_path, methods=METHODS, limit=1, progress=False)
    config = read_config(tmp_path)
    assert [s["registrations"] for s in config["sessions"]] == [1, 1]
    assert len(load_results(tmp_path)) == 2
    with pytest.raises(ValueError, match="seed"):
        run_eval([suite_dir], tmp_path, methods=METHODS, limit=1, seed=5, progress=False)


# ---------------------------------------------------------------------------- peers


@pytest.mark.slow
@pytest.mark.parametrize(
    ("method", "module"), [("kiss_matcher", "kiss_matcher"), ("small_gicp", "small_gicp")]
)
def test_peers_run_on_a_tiny_instance(method, module, suite_dir, tmp_path):
    pytest.importorskip(module, reason=f"{module} is not installed")
    run_eval([suite_dir], tmp_path, methods=[method], limit=2, progress=False)
    frame = load_results(tmp_path)
    assert len(frame) == 2 and frame["error"].isna().all()
    assert frame["transformation"].map(len).eq(4).all()


_THREADS_AROUND_KISS_MATCHER = """
import os, numpy as np, open3d as o3d
from o3d_spectral.harness.peers import kiss_matcher
o3d.utility.set_max_threads(1)  # as the harness's workers run
cloud = o3d.geometry.PointCloud(
    o3d.utility.Vector3dVector(np.random.default_rng(0).random((4000, 3))))
cloud.estimate_normals()
allowed, before = os.sched_getaffinity(0), len(os.listdir("/proc/self/task"))
kiss_matcher(cloud, o3d.geometry.PointCloud(cloud), 0.05, 0)
print(len(os.listdir("/proc/self/task")) - before, os.sched_getaffinity(0) == allowed)
"""


@pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2, reason="needs two CPUs")
def test_kiss_matcher_starts_no_thread_and_leaves_the_affinity_as_it_was():
    pytest.importorskip("kiss_matcher", reason="kiss_matcher is not installed")
    # On several threads its oneTBB pool made a seeded run's rows differ from run to run.
    env = os.environ | {"OMP_NUM_THREADS": "1"}
    done = subprocess.run([sys.executable, "-c", _THREADS_AROUND_KISS_MATCHER], env=env,
                          capture_output=True, text=True, check=True)
    assert done.stdout.split() == ["0", "True"]


@pytest.mark.slow
def test_tuned_fpfh_skips_the_tuning_split_and_is_reported_off_it(suite_dir, tmp_path):
    from o3d_spectral.harness.report import make_report

    methods = ["fpfh_ransac_tuned", "icp_point_to_plane"]
    run_eval([suite_dir], tmp_path, methods=methods, limit=2, progress=False)
    frame = load_results(tmp_path)
    tuned = frame[frame["method"] == "fpfh_ransac_tuned"]
    assert list(tuned["index"]) == [1]  # index 0 is in the tuning split
    assert tuned["success"].all()
    written = make_report(tmp_path, tmp_path / "report")
    held_out = (tmp_path / "report" / "summary_held_out.csv").read_text().splitlines()
    assert "summary_held_out.md" in written and len(held_out) == 1 + len(methods)


def test_a_missing_peer_says_how_to_install(monkeypatch):
    from o3d_spectral.harness import get_method, methods

    monkeypatch.setitem(methods.UNAVAILABLE, "not_here", "the not-here package: pip install x")
    with pytest.raises(ValueError, match="not-here package"):
        get_method("not_here")


# ------------------------------------------------------------- killed or interrupted


def _descendants(pid: int) -> set[int]:
    """Every live process started by ``pid``, at any depth (Linux ``/proc``)."""
    found, todo = set(), [pid]
    while todo:
        parent = todo.pop()
        for task in Path(f"/proc/{parent}/task").glob("*"):
            try:
                children = (task / "children").read_text().split()
            except OSError:
                continue
            for child in map(int, children):
                if child not in found:
                    found.add(child)
                    todo.append(child)
    return found


def _alive(pid: int) -> bool:
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return False
    return "\nState:\tZ" not in status  # a zombie has ended (only not yet reaped)


#: A method that outlasts the tests below: the eval is still running when they stop it.
SLOW_PLUGIN = """
import time

import numpy as np

from o3d_spectral.harness.methods import register_method


@register_method("slow_identity")
def slow_identity(source, target, voxel_size, seed):
    time.sleep(300)
    return np.eye(4), {}
"""


def _eval_with_workers(suite_dir, tmp_path) -> tuple[subprocess.Popen, set[int]]:
    """``o3d-spectral eval`` with two workers, once they have written a row, each task of
    one of its methods lasting minutes; and its processes."""
    root = str(Path(o3d_spectral.__file__).resolve().parents[1])
    (tmp_path / "plugins").mkdir()
    (tmp_path / "plugins" / "slow_plugin.py").write_text(SLOW_PLUGIN)
    path = [root, str(tmp_path / "plugins"), os.environ.get("PYTHONPATH", "")]
    env = os.environ | {"PYTHONPATH": os.pathsep.join(path)}
    out = tmp_path / "out"
    command = [sys.executable, "-m", "o3d_spectral.cli", "eval", "--suite", str(suite_dir),
               "--out", str(out), "--quiet", "--workers", "2", "--plugin", "slow_plugin",
               "--methods", "fpfh_ransac", "slow_identity"]
    run = subprocess.Popen(command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                           text=True, start_new_session=True)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and run.poll() is None and not (
        len(_descendants(run.pid)) >= 3
        and any(f.stat().st_size for f in (out / "results").glob("*.jsonl"))
    ):  # the tracker and two workers, at work
        time.sleep(0.1)
    processes = _descendants(run.pid)
    assert run.poll() is None, run.stderr.read()
    assert len(processes) >= 3, processes
    return run, processes


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_killed_eval_leaves_no_process_behind(suite_dir, tmp_path):
    run, processes = _eval_with_workers(suite_dir, tmp_path)
    run.kill()  # SIGKILL: no handler of the parent runs
    run.wait(timeout=10)
    deadline = time.monotonic() + 5.0
    while any(map(_alive, processes)) and time.monotonic() < deadline:
        time.sleep(0.1)
    left = [pid for pid in processes if _alive(pid)]
    for pid in left:  # do not leave them to the next test either
        os.kill(pid, 9)
    assert not left, f"{len(left)} of {len(processes)} processes outlived the killed eval"
    run.stderr.read()  # a reader of its stderr is not kept waiting


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_interrupted_eval_stops_with_one_line_and_status_130(suite_dir, tmp_path):
    run, processes = _eval_with_workers(suite_dir, tmp_path)
    os.killpg(run.pid, 2)  # Ctrl-C: the terminal signals the whole process group
    _, stderr = run.communicate(timeout=30)
    assert run.returncode == 130
    assert len(stderr.strip().splitlines()) == 1 and "interrupted" in stderr, stderr
    time.sleep(1.0)
    assert not [pid for pid in processes if _alive(pid)]


@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")
def test_an_interrupt_dropped_by_a_finaliser_is_still_flagged():
    """Python drops a ``KeyboardInterrupt`` raised inside a finaliser; the pool's wait for
    rows reads the flag instead, so that Ctrl-C is never lost."""
    from o3d_spectral.harness.executors import interrupt_flag

    class Finalised:
        def __del__(self):
            os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C while a finaliser runs
            for _ in range(1000):  # the handler runs between bytecodes, here
                pass

    with interrupt_flag() as flag:
        Finalised()  # the interrupt raised in __del__ is dropped ("Exception ignored")
        gc.collect()
        assert flag.is_set()  # reached: nothing was raised here
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
