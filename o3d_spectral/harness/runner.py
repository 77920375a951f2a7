"""The evaluation loop: every method on every instance of some suites, resumable.

What the run folder holds is described in :mod:`o3d_spectral.harness.records`.

Each registration runs in a worker process with one thread (``OMP_NUM_THREADS=1``), so
results do not depend on the number of workers and times compare per core. A method's
seed depends on the run seed, the suite (condition and seed), the instance and the method,
never on the order of execution. Wall time is measured around the method call only.
"""

from __future__ import annotations

import contextlib
import datetime
import functools
import importlib
import json
import os
import time
import zlib
from collections.abc import Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass
from multiprocessing import get_context
from pathlib import Path

import numpy as np

from o3d_spectral.harness._optional import require
from o3d_spectral.harness.methods import get_method, method_names
from o3d_spectral.harness.metrics import (
    SuccessCriteria,
    convergence_curves,
    indistinguishable,
    instance_metrics,
    registration_fit,
)
from o3d_spectral.harness.records import (
    CURVE_COLUMNS,
    RESULTS_FILE,
    done_keys,
    prepare_config,
    session_record,
    suite_name,
    write_config,
    write_results_table,
)
from o3d_spectral.synthetic.suite import Suite, load_suite

__all__ = ["run_eval", "task_seed"]

_METADATA = (
    "condition",
    "object",
    "init_angle_deg",
    "init_offset_m",
    "visible_fraction",
    "occlusion",
)
_SINGLE_THREAD = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


@dataclass(frozen=True)
class _Task:
    suite_dir: str
    suite: str
    index: int
    method: str
    seed: int
    voxel_size: float
    criteria: SuccessCriteria


def task_seed(seed: int, condition: str, suite_seed: int, index: int, method: str) -> int:
    """Seed of one registration, in [0, 2**31): a hash of the run seed, the suite's
    condition and seed, the instance index and the method name."""
    words = [seed, suite_seed, index, zlib.crc32(condition.encode()), zlib.crc32(method.encode())]
    return int(np.random.SeedSequence(words).generate_state(1)[0] & 0x7FFFFFFF)


@functools.cache
def _suite(suite_dir: str) -> Suite:
    return load_suite(suite_dir)


def _init_worker(plugins: tuple[str, ...]) -> None:
    import open3d as o3d

    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    # Open3D ignores OMP_NUM_THREADS; on several threads its sums (ICP, RANSAC, FGR) change
    # from run to run, so seeded runs of its methods did not repeat.
    o3d.utility.set_max_threads(1)
    for module in plugins:
        importlib.import_module(module)


def _compact(values: Sequence[float]) -> list[float]:
    return [float(f"{v:.6g}") for v in values]


def _run_task(task: _Task) -> dict:
    """Run one method on one instance (in a worker) and return its results row. A missing
    or corrupt instance file raises (naming it), which stops the eval: it is not the
    method's failure."""
    instance = _suite(task.suite_dir)[task.index]
    method = get_method(task.method)
    start = time.perf_counter()
    try:
        transformation, info = method(instance.source, instance.target, task.voxel_size, task.seed)
        error = None
    except Exception as exc:  # a failing method is a failed instance, not a failed run
        transformation, info, error = None, {}, f"{type(exc).__name__}: {exc}"
    seconds = time.perf_counter() - start
    row = {"suite": task.suite, "index": task.index, "method": task.method}
    row |= {key: instance.metadata.get(key) for key in _METADATA}
    row |= {"seed": task.seed, "time_s": seconds, "error": error}
    if transformation is None:
        row["success"] = False
        return row
    row |= instance_metrics(transformation, instance, criteria=task.criteria)
    # A wrong pose: can the observation rule it out? (None for a success.)
    row["indistinguishable"] = (
        None if row["success"] else indistinguishable(transformation, instance)
    )
    row["fitness"], row["inlier_rmse"] = registration_fit(
        transformation, instance, distance=task.voxel_size
    )
    row |= {
        "iterations": info.get("iterations"),
        "converged": info.get("converged"),
        "translation_gradient_norm_m": info.get("translation_gradient_norm"),
        "rotation_gradient_norm_rad": info.get("rotation_gradient_norm"),
        "transformation": np.asarray(transformation).tolist(),
    }
    if info.get("trajectory") is not None:
        rotation, translation = convergence_curves(info["trajectory"], instance)
        row[CURVE_COLUMNS[0]], row[CURVE_COLUMNS[1]] = _compact(rotation), _compact(translation)
    return row


@contextlib.contextmanager
def _single_threaded_children() -> Iterator[None]:
    """Environment inherited by the worker processes started inside the block."""
    saved = {name: os.environ.get(name) for name in _SINGLE_THREAD}
    os.environ.update(dict.fromkeys(_SINGLE_THREAD, "1"))
    try:
        yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


def _tasks(
    suites: list[Suite],
    methods: list[str],
    done: set,
    *,
    seed: int,
    voxel_size: float,
    criteria: SuccessCriteria,
    limit: int | None,
) -> list[_Task]:
    tasks = []
    for suite in suites:
        name = suite_name(suite)
        for index in range(len(suite) if limit is None else min(limit, len(suite))):
            condition = suite.manifest["instances"][index].get("condition", suite.condition)
            for method in methods:
                if (name, index, method) in done:
                    continue
                method_seed = task_seed(seed, condition, suite.manifest["seed"], index, method)
                tasks.append(
                    _Task(str(suite.root), name, index, method, method_seed, voxel_size, criteria)
                )
    return tasks


def _execute(
    tasks: list[_Task], *, workers: int, plugins: tuple[str, ...], progress: bool
) -> Iterator[dict]:
    """Results rows of ``tasks`` as they complete, from single-threaded worker processes."""
    bar = require("tqdm").tqdm(total=len(tasks), desc="eval", unit="reg", disable=not progress)
    with _single_threaded_children():
        pool = ProcessPoolExecutor(
            max_workers=workers,
            mp_context=get_context("spawn"),
            initializer=_init_worker,
            initargs=(plugins,),
        )
        try:
            for future in as_completed([pool.submit(_run_task, task) for task in tasks]):
                yield future.result()
                bar.update()
        finally:  # on an interrupt, drop the queued tasks instead of running them all
            pool.shutdown(wait=True, cancel_futures=True)
            bar.close()


def _inputs(
    suites: Sequence[str | Path],
    methods: Sequence[str] | None,
    *,
    workers: int,
    voxel_size: float,
    limit: int | None,
    plugins: Sequence[str],
) -> tuple[list[str], list[Suite]]:
    """Check the arguments of :func:`run_eval`, import the plugins; the method names and
    the loaded suites."""
    if not suites:
        raise ValueError("suites must name at least one suite folder")
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    if not voxel_size > 0:
        raise ValueError(f"voxel_size must be positive (metres), got {voxel_size}")
    if limit is not None and limit < 1:
        raise ValueError(f"limit must be >= 1, got {limit}")
    for module in plugins:
        importlib.import_module(module)
    methods = list(method_names() if methods is None else methods)
    for method in methods:
        get_method(method)
    loaded = [load_suite(path) for path in suites]
    names = [suite_name(suite) for suite in loaded]
    if len(set(names)) != len(names):
        raise ValueError(f"suites must have distinct folder names, got {names}")
    return methods, loaded


def _session(
    out: Path,
    config: dict,
    tasks: list[_Task],
    methods: list[str],
    *,
    workers: int,
    plugins: tuple[str, ...],
    progress: bool,
) -> None:
    """Run ``tasks``, appending each row to ``results.jsonl`` as it comes, then record the
    session in ``config.json`` (also when interrupted)."""
    started, start = datetime.datetime.now().isoformat(timespec="seconds"), time.perf_counter()
    done = 0
    try:
        with (out / RESULTS_FILE).open("a") as sink:
            for row in _execute(tasks, workers=workers, plugins=plugins, progress=progress):
                sink.write(json.dumps(row) + "\n")
                sink.flush()
                done += 1
    finally:  # an interrupted session still counts its time and registrations
        config["sessions"].append(
            session_record(
                methods,
                started=started,
                seconds=round(time.perf_counter() - start, 1),
                registrations=done,
                complete=done == len(tasks),
                workers=workers,
            )
        )
        write_config(out, config)


def run_eval(
    suites: Sequence[str | Path],
    out_dir: str | Path,
    *,
    methods: Sequence[str] | None = None,
    workers: int = 1,
    voxel_size: float = 0.008,
    seed: int = 0,
    limit: int | None = None,
    criteria: SuccessCriteria | None = None,
    plugins: Sequence[str] = (),
    progress: bool = True,
) -> Path:
    """Run ``methods`` on the instances of ``suites``; results go to ``out_dir``.

    Pairs (instance, method) already in ``out_dir/results.jsonl`` are skipped, so calling
    it again resumes an interrupted run, or adds methods or suites to a finished one.

    Parameters
    ----------
    suites : sequence of str or Path
        Suite folders (``make-suite`` output); their folder names must differ.
    out_dir : str or Path
        Run folder (created if missing).
    methods : sequence of str, optional
        Registered method names (:func:`~o3d_spectral.harness.methods.method_names`);
        all when None.
    workers : int, optional
        Worker processes, each single-threaded; results do not depend on it.
    voxel_size : float, optional
        Voxel edge shared by all methods, metres (the paper's 8 mm by default).
    seed : int, optional
        Run seed, from which each registration's seed is derived (:func:`task_seed`).
    limit : int, optional
        Only the first ``limit`` instances of each suite (quick runs).
    criteria : SuccessCriteria, optional
        Success thresholds (5 degrees and 1 cm when None).
    plugins : sequence of str, optional
        Modules imported first (in every worker too), e.g. one registering more methods.
    progress : bool, optional
        Show a tqdm progress bar.

    Returns
    -------
    Path
        The per-instance table ``out_dir/results.csv``.
    """
    methods, loaded = _inputs(
        suites, methods, workers=workers, voxel_size=voxel_size, limit=limit, plugins=plugins
    )
    criteria = criteria or SuccessCriteria()

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    settings = {"voxel_size": voxel_size, "seed": seed, "criteria": asdict(criteria)}
    config = prepare_config(out, loaded, settings, methods)
    tasks = _tasks(
        loaded,
        methods,
        done_keys(out / RESULTS_FILE),
        seed=seed,
        voxel_size=voxel_size,
        criteria=criteria,
        limit=limit,
    )
    write_config(out, config)
    plugins = tuple(plugins)
    _session(out, config, tasks, methods, workers=workers, plugins=plugins, progress=progress)
    return write_results_table(out)
