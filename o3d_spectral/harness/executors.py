"""Where an evaluation's registrations run: a local process pool (the default) or a Dask
distributed cluster (``eval --cluster``).

Both take the same task objects and a module-level function ``run(task, plugins)`` that
returns the task's row; what a row holds depends only on the task (its seed included),
never on the executor, the number of workers or the order of completion. Workers run one
registration at a time on one thread: the pool's processes inherit
``OMP_NUM_THREADS=1`` (and the BLAS variables); a Dask nanny sets the same variables in
its workers by default (``distributed.nanny.pre-spawn-environ``), and ``--cluster local``
starts workers of one thread. Workers of an external cluster must be started with
``--nthreads 1``, see the same o3d-spectral version and read the suite folders at the same
paths.
"""

from __future__ import annotations

import contextlib
import logging
import os
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from multiprocessing import get_context
from pathlib import Path

from o3d_spectral import _extras

__all__ = ["SINGLE_THREAD", "dask_cluster", "local_pool", "require_distributed"]

SINGLE_THREAD = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def require_distributed():
    """``dask.distributed``, or ``ImportError`` saying how to install the ``cluster`` extra."""
    return _extras.require("dask.distributed", "eval --cluster")


@contextlib.contextmanager
def _single_threaded_children() -> Iterator[None]:
    """Environment inherited by the worker processes started inside the block."""
    saved = {name: os.environ.get(name) for name in SINGLE_THREAD}
    os.environ.update(dict.fromkeys(SINGLE_THREAD, "1"))
    try:
        yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


@contextlib.contextmanager
def local_pool(
    workers: int, initializer: Callable, plugins: tuple[str, ...]
) -> Iterator[Callable[[Callable, Sequence], Iterator[dict]]]:
    """A pool of ``workers`` spawned single-threaded processes (each calls
    ``initializer(plugins)`` first); yields ``submit(run, tasks)``, an iterator of the rows
    of ``run(task)`` as they complete. Queued tasks are dropped on an interrupt."""
    with _single_threaded_children():
        pool = ProcessPoolExecutor(
            max_workers=workers,
            mp_context=get_context("spawn"),
            initializer=initializer,
            initargs=(plugins,),
        )

    def submit(run: Callable, tasks: Sequence) -> Iterator[dict]:
        for future in as_completed([pool.submit(run, task) for task in tasks]):
            yield future.result()

    try:
        yield submit
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _client(distributed, address: str, workers: int):
    """A client of the cluster at ``address``: ``"local"`` (a new ``LocalCluster`` of
    ``workers`` one-thread worker processes on 127.0.0.1), a scheduler file (JSON, as
    ``dask scheduler --scheduler-file`` writes) or a scheduler address."""
    if address == "local":
        with _single_threaded_children():
            cluster = distributed.LocalCluster(
                n_workers=workers,
                threads_per_worker=1,
                processes=True,
                host="127.0.0.1",
                dashboard_address=None,
                silence_logs=logging.ERROR,
            )
        return distributed.Client(cluster), cluster
    if Path(address).is_file():
        return distributed.Client(scheduler_file=address), None
    return distributed.Client(address), None


def _worker_count(client) -> int:
    try:  # newer versions list only a few workers unless asked for all
        info = client.scheduler_info(n_workers=-1)
    except TypeError:
        info = client.scheduler_info()
    return len(info["workers"])


@contextlib.contextmanager
def dask_cluster(
    address: str, workers: int, plugins: tuple[str, ...]
) -> Iterator[tuple[Callable[[Callable, Sequence], Iterator[dict]], int]]:
    """A Dask cluster (see :func:`_client` for ``address``); yields ``submit(run, tasks)``
    (rows of ``run(task, plugins)`` as they complete) and the number of workers. Tasks not
    done are cancelled on an interrupt; a cluster started here is closed."""
    distributed = require_distributed()
    client, cluster = _client(distributed, address, workers)
    futures: list = []

    def submit(run: Callable, tasks: Sequence) -> Iterator[dict]:
        futures.extend(client.submit(run, task, plugins, pure=False) for task in tasks)
        for future in distributed.as_completed(futures):
            yield future.result()

    try:
        yield submit, _worker_count(client)
    finally:
        with contextlib.suppress(Exception):
            client.cancel(futures)
        client.close()
        if cluster is not None:
            cluster.close()
