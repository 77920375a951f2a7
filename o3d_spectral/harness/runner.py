"""The evaluation loop: every method on every instance of some suites, resumable.

What the run folder holds is described in :mod:`o3d_spectral.harness.records`.

Each registration runs in a worker process with one thread (``OMP_NUM_THREADS=1``), so
results do not depend on the number of workers and times compare per core. The workers are
a local process pool or a Dask cluster (:mod:`~o3d_spectral.harness.executors`); which
instances run is chosen by :mod:`~o3d_spectral.harness.selection` (limit, sample, shard).
A method's seed depends on the run seed, the suite (condition and seed), the instance and
the method, never on the order of execution nor on what runs it, so the rows are the same
whatever runs them. Wall time is measured around the method call only.
"""

from __future__ import annotations

import datetime
import functools
import importlib
import json
import time
import zlib
from collections.abc import Iterator, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from o3d_spectral.common.checks import check_voxel_size
from o3d_spectral.harness._optional import require
from o3d_spectral.harness.bop import BopSet
from o3d_spectral.harness.executors import dask_cluster, local_pool
from o3d_spectral.harness.methods import get_method, method_names, method_settings
from o3d_spectral.harness.metrics import (
    SuccessCriteria,
    convergence_curves,
    indistinguishable,
    instance_metrics,
    registration_fit,
)
from o3d_spectral.harness.pairs import PairSet
from o3d_spectral.harness.records import (
    CURVE_COLUMNS,
    append_row,
    done_keys,
    new_session_id,
    open_results,
    prepare_session,
    session_record,
    suite_name,
    write_results_table,
    write_session,
)
from o3d_spectral.harness.selection import in_tuning_split, parse_shard, selected_indices
from o3d_spectral.harness.sets import open_set, set_spec
from o3d_spectral.io.folder_lock import folder_lock
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


@dataclass(frozen=True)
class _Task:
    spec: tuple  # what opens the instance set (:func:`~o3d_spectral.harness.sets.open_set`)
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
def _init_worker(plugins: tuple[str, ...]) -> None:
    import open3d as o3d

    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    # Open3D ignores OMP_NUM_THREADS; on several threads its sums (ICP, RANSAC, FGR) change
    # from run to run, so seeded runs of its methods did not repeat.
    o3d.utility.set_max_threads(1)
    for module in plugins:
        importlib.import_module(module)


def _run_on_worker(task: _Task, plugins: tuple[str, ...]) -> dict:
    """:func:`_run_task` in a Dask worker, set up (one thread, plugins) on its first task."""
    _init_worker(plugins)
    return _run_task(task)


def _compact(values: Sequence[float]) -> list[float]:
    return [float(f"{v:.6g}") for v in values]


def _run_task(task: _Task) -> dict:
    """Run one method on one instance (in a worker) and return its results row. A missing
    or corrupt instance file raises (naming it), which stops the eval: it is not the
    method's failure."""
    instances = open_set(task.spec)
    instance = instances[task.index]
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
    if isinstance(instances, Suite):  # a bundled model's mesh tells what the view shows
        # A wrong pose: can the observation rule it out? (None for a success.)
        row["indistinguishable"] = (
            None if row["success"] else indistinguishable(transformation, instance)
        )
    else:  # the benchmark's own scores: BOP's errors, or registration recall's
        row |= instances.score(transformation, task.index)
    row["fitness"], row["inlier_rmse"] = registration_fit(
        transformation, instance, distance=task.voxel_size
    )
    row |= {
        "iterations": info.get("iterations"),
        "converged": info.get("converged"),
        "translation_gradient_norm_m": info.get("translation_gradient_norm"),
        "rotation_gradient_norm_rad": info.get("rotation_gradient_norm"),
        "confidence": info.get("confidence"),
        "transformation": np.asarray(transformation).tolist(),
    }
    if info.get("trajectory") is not None:
        rotation, translation = convergence_curves(info["trajectory"], instance)
        row[CURVE_COLUMNS[0]], row[CURVE_COLUMNS[1]] = _compact(rotation), _compact(translation)
    return row


@dataclass(frozen=True)
class _Selection:
    """Which instances a session runs (:func:`~o3d_spectral.harness.selection.selected_indices`)."""

    limit: int | None = None
    sample: int | None = None
    shard: tuple[int, int] | None = None


def _tasks(
    suites: list[Suite | BopSet | PairSet],
    methods: list[str],
    done: set,
    *,
    seed: int,
    voxel_size: float,
    criteria: SuccessCriteria,
    selection: _Selection,
) -> list[_Task]:
    # A method tuned on the tuning split is run (and reported) on the other instances only.
    tuned = {m for m in methods if "tuning_split" in method_settings(m)}
    tasks = []
    for suite in suites:
        name, suite_seed = suite_name(suite), suite.manifest["seed"]
        indices = selected_indices(
            len(suite),
            condition=suite.condition,
            suite_seed=suite_seed,
            limit=selection.limit,
            sample=selection.sample,
            seed=seed,
            shard=selection.shard,
        )
        for index in indices:
            condition = suite.manifest["instances"][index].get("condition", suite.condition)
            for method in methods:
                if (name, index, method) in done or (method in tuned and in_tuning_split(index)):
                    continue
                method_seed = task_seed(seed, condition, suite_seed, index, method)
                tasks.append(
                    _Task(set_spec(suite), name, index, method, method_seed, voxel_size, criteria)
                )
    return tasks


def _execute(
    tasks: list[_Task],
    *,
    workers: int,
    plugins: tuple[str, ...],
    progress: bool,
    cluster: str | None,
    session: dict,
) -> Iterator[dict]:
    """Results rows of ``tasks`` as they complete, from single-threaded workers: a local
    process pool, or the Dask cluster at ``cluster``; ``session["workers"]`` is set to the
    number of workers."""
    bar = require("tqdm").tqdm(total=len(tasks), desc="eval", unit="reg",
                               disable=None if progress else True)  # on a terminal only
    try:
        if cluster is None:
            with local_pool(workers, _init_worker, plugins) as submit:
                yield from _counted(submit(_run_task, tasks), bar)
        else:
            with dask_cluster(cluster, workers, plugins) as (submit, count):
                session["workers"] = count
                yield from _counted(submit(_run_on_worker, tasks), bar)
    finally:
        bar.close()


def _counted(rows: Iterator[dict], bar) -> Iterator[dict]:
    for row in rows:
        yield row
        bar.update()


def _inputs(
    suites: Sequence[str | Path | BopSet | PairSet],
    methods: Sequence[str] | None,
    *,
    workers: int,
    voxel_size: float,
    selection: _Selection,
    plugins: Sequence[str],
) -> tuple[list[str], list[Suite | BopSet | PairSet]]:
    """Check the arguments of :func:`run_eval`, import the plugins; the method names and
    the loaded suites."""
    if not suites:
        raise ValueError("suites must name at least one suite folder")
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    check_voxel_size(voxel_size)
    for name in ("limit", "sample"):
        value = getattr(selection, name)
        if value is not None and value < 1:
            raise ValueError(f"{name} must be >= 1, got {value}")
    if selection.limit is not None and selection.sample is not None:
        raise ValueError("give limit or sample, not both")
    for module in plugins:
        importlib.import_module(module)
    methods = list(method_names() if methods is None else methods)
    for method in methods:
        get_method(method)
    loaded = [s if isinstance(s, BopSet | PairSet) else load_suite(s) for s in suites]
    names = [suite_name(suite) for suite in loaded]
    if len(set(names)) != len(names):
        raise ValueError(f"suites must have distinct folder names, got {names}")
    return methods, loaded


def _session(
    out: Path,
    entry: dict,
    tasks: list[_Task],
    *,
    record: dict,
    cluster: str | None,
    plugins: tuple[str, ...],
    progress: bool,
) -> None:
    """Run ``tasks``, appending each row to the session's results file as it comes; the
    session's file is written first and again at the end (also when interrupted)."""
    record = session_record(entry["methods"], **record)
    write_session(out, entry, record)
    start, done = time.perf_counter(), 0
    try:
        with open_results(out, record["id"]) as sink:
            for row in _execute(
                tasks,
                workers=record["workers"],
                plugins=plugins,
                progress=progress,
                cluster=cluster,
                session=record,
            ):
                append_row(sink, row)
                done += 1
    finally:  # an interrupted session still counts its time and registrations
        record |= {"seconds": round(time.perf_counter() - start, 1), "registrations": done}
        record["complete"] = done == len(tasks)
        write_session(out, entry, record)


def run_eval(
    suites: Sequence[str | Path | BopSet | PairSet],
    out_dir: str | Path,
    *,
    methods: Sequence[str] | None = None,
    workers: int = 1,
    voxel_size: float = 0.008,
    seed: int = 0,
    limit: int | None = None,
    sample: int | None = None,
    shard: str | tuple[int, int] | None = None,
    cluster: str | None = None,
    criteria: SuccessCriteria | None = None,
    plugins: Sequence[str] = (),
    progress: bool = True,
) -> Path:
    """Run ``methods`` on the instances of ``suites``; results go to ``out_dir``.

    Pairs (instance, method) already in ``out_dir`` are skipped, so calling it again
    resumes an interrupted run, or adds methods or suites to a finished one. Another call
    writing ``out_dir`` meanwhile is refused (``FolderBusyError``,
    :mod:`~o3d_spectral.io.folder_lock`) but for the shards ``i/n`` of one run with the
    same settings, each session writing its own files (:mod:`~o3d_spectral.harness.records`).

    Parameters
    ----------
    suites : sequence of str, Path, BopSet or PairSet
        Suite folders (``make-suite`` output), or the instances of a BOP dataset
        (:class:`~o3d_spectral.harness.bop.BopSet`) or of a 3DMatch-layout scene
        (:class:`~o3d_spectral.harness.pairs.PairSet`), whose rows also hold the
        benchmark's scores (their ``score``); their names must differ.
    out_dir : str or Path
        Run folder (created if missing).
    methods : sequence of str, optional
        Registered method names (:func:`~o3d_spectral.harness.methods.method_names`);
        all when None.
    workers : int, optional
        Worker processes, each single-threaded (with ``cluster="local"``: the cluster's);
        results do not depend on it.
    voxel_size : float, optional
        Voxel edge shared by all methods, metres (the paper's 8 mm by default).
    seed : int, optional
        Run seed, from which each registration's seed is derived (:func:`task_seed`), and
        the seed of ``sample``.
    limit : int, optional
        Only the first ``limit`` instances of each suite (quick runs).
    sample : int, optional
        Only ``sample`` instances of each suite drawn at random (seeded by ``seed`` and the
        suite); not with ``limit``.
    shard : str or (int, int), optional
        ``"i/n"``: only the instances of shard ``i`` of ``n``
        (:func:`~o3d_spectral.harness.selection.in_shard`), of those ``limit`` or
        ``sample`` select; ``n`` sessions with shards ``0/n`` .. ``n-1/n`` run each
        instance once.
    cluster : str, optional
        Run on a Dask cluster instead of a local process pool: ``"local"`` (a
        ``LocalCluster`` of ``workers`` one-thread workers), a scheduler address
        (``tcp://host:8786``) or a scheduler file. Needs the ``cluster`` extra.
    criteria : SuccessCriteria, optional
        Success thresholds (5 degrees and 1 cm when None).
    plugins : sequence of str, optional
        Modules imported first (in every worker too), e.g. one registering more methods.
    progress : bool, optional
        Show a tqdm progress bar, when stderr is a terminal (not in a log or a pipe).

    Returns
    -------
    Path
        The per-instance table ``out_dir/results.csv``.
    """
    shard = parse_shard(shard) if isinstance(shard, str) else shard
    selection = _Selection(limit, sample, None if shard is None else tuple(shard))
    methods, loaded = _inputs(
        suites, methods, workers=workers, voxel_size=voxel_size, selection=selection,
        plugins=plugins,
    )
    criteria = criteria or SuccessCriteria()
    out = Path(out_dir)
    settings = {"voxel_size": voxel_size, "seed": seed, "criteria": asdict(criteria)}
    part = None if shard is None else f"{shard[0]}/{shard[1]}"  # the shards of one run share
    shards = None if shard is None else json.dumps({"of": shard[1], **settings}, sort_keys=True)
    with folder_lock(out, "o3d-spectral eval", group=shards, part=part):
        entry = prepare_session(out, loaded, settings, methods)
        tasks = _tasks(loaded, methods, done_keys(out), seed=seed, voxel_size=voxel_size,
                       criteria=criteria, selection=selection)
        record = {
            "id": new_session_id(),
            "started": datetime.datetime.now().isoformat(timespec="seconds"),
            "seconds": 0.0,
            "registrations": 0,
            "planned": len(tasks),
            "complete": not tasks,
            "executor": cluster or "local pool",
            "workers": workers,
            "selection": {"limit": limit, "sample": sample},
            "shard": part,
        }
        _session(
            out, entry, tasks, record=record, cluster=cluster, plugins=tuple(plugins),
            progress=progress,
        )
        return write_results_table(out)
