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
import ctypes
import importlib
import logging
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from multiprocessing import get_context
from pathlib import Path

from o3d_spectral.common import extras
from o3d_spectral.harness.constants import INTERRUPT_POLL, PARENT_POLL

__all__ = ["SINGLE_THREAD", "StopFlag", "dask_cluster", "interrupt_flag", "local_pool",
           "require_distributed"]

SINGLE_THREAD = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
_PR_SET_PDEATHSIG = 1  # linux/prctl.h


def require_distributed():
    """``dask.distributed``, or ``ImportError`` saying how to install the ``cluster`` extra."""
    return extras.require("dask.distributed", "eval --cluster")


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


def _end_with_parent(parent: int) -> None:
    """Make this worker process end when the process ``parent`` ends, however it ends.

    A killed parent (SIGKILL) cannot stop its workers, and a spawned worker otherwise
    outlives it, holding its memory and the pipe of multiprocessing's resource tracker
    (which then outlives it too). On Linux the kernel sends this process SIGKILL when the
    parent dies (``prctl(PR_SET_PDEATHSIG)``); everywhere, a daemon thread sees the parent
    change (``os.getppid()``) within :data:`PARENT_POLL` seconds and exits.
    """
    if sys.platform.startswith("linux"):
        with contextlib.suppress(Exception):  # no libc by that name: the thread suffices
            ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PARENT_POLL)
        os._exit(1)

    threading.Thread(target=watch, name="parent-watch", daemon=True).start()


def _pool_worker(parent: int, initializer: tuple[str, str], plugins: tuple[str, ...]) -> None:
    """A pool worker's set-up: ended with its parent, deaf to Ctrl-C (the terminal sends
    SIGINT to the whole process group; the parent alone decides, and ends the workers),
    then ``initializer(plugins)``, named (module, function) so that its module's imports
    (seconds: Open3D, the methods) come after the worker watches its parent."""
    _end_with_parent(parent)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    module, name = initializer
    getattr(importlib.import_module(module), name)(plugins)


def _terminate(pool: ProcessPoolExecutor) -> None:
    """End the pool's worker processes now (an interrupt: their tasks are abandoned)."""
    processes = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for process in processes:
        with contextlib.suppress(Exception):
            process.terminate()
    for process in processes:
        with contextlib.suppress(Exception):
            process.join(timeout=5)
            if process.is_alive():
                process.kill()


class StopFlag(threading.Event):
    """Set by a stop (Ctrl-C, or SIGTERM where the program raises on it); ``stop`` is the
    exception it raised, to raise again where it can propagate."""

    stop: KeyboardInterrupt = KeyboardInterrupt()


@contextlib.contextmanager
def interrupt_flag() -> Iterator[StopFlag]:
    """A flag set by Ctrl-C (SIGINT) or SIGTERM while the block runs, beside the exception
    their handlers raise (``KeyboardInterrupt``, or the CLI's ``Terminated``): Python
    drops an exception raised where it cannot propagate (a finaliser, a weak-reference
    callback, running when the signal arrives), and the stop must not be lost with it.
    Only for a signal whose handler is Python code, in the main thread; the handlers are
    restored after."""
    flag = StopFlag()
    if threading.current_thread() is not threading.main_thread():
        yield flag
        return
    previous = {number: signal.getsignal(number) for number in (signal.SIGINT, signal.SIGTERM)}

    def stopped(signum, frame):
        try:
            previous[signum](signum, frame)
        except KeyboardInterrupt as stop:
            flag.stop = stop
            flag.set()
            raise

    for number, handler in previous.items():
        if callable(handler):
            signal.signal(number, stopped)
    try:
        yield flag
    finally:
        for number, handler in previous.items():
            if callable(handler):
                signal.signal(number, handler)


@contextlib.contextmanager
def local_pool(
    workers: int, initializer: Callable, plugins: tuple[str, ...]
) -> Iterator[Callable[[Callable, Sequence], Iterator[dict]]]:
    """A pool of ``workers`` spawned single-threaded processes (each calls
    ``initializer(plugins)`` first); yields ``submit(run, tasks)``, an iterator of the rows
    of ``run(task)`` as they complete. The workers end with this process, even killed
    (:func:`_end_with_parent`), and ignore Ctrl-C; on an interrupt (raised, or only
    flagged: :func:`interrupt_flag`) or any error the queued tasks are dropped and the
    workers ended at once."""
    with _single_threaded_children():
        pool = ProcessPoolExecutor(
            max_workers=workers,
            mp_context=get_context("spawn"),
            initializer=_pool_worker,
            initargs=(os.getpid(), (initializer.__module__, initializer.__qualname__), plugins),
        )

    def submit(run: Callable, tasks: Sequence) -> Iterator[dict]:
        pending = {pool.submit(run, task) for task in tasks}
        while pending:
            done, pending = wait(pending, timeout=INTERRUPT_POLL, return_when=FIRST_COMPLETED)
            if interrupt.is_set():
                raise interrupt.stop
            for future in done:
                yield future.result()

    try:
        with interrupt_flag() as interrupt:
            yield submit
    except BaseException:
        _terminate(pool)
        raise
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
