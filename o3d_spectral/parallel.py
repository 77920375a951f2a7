"""Independent work of one call spread over threads.

The global search's placements and climbs are independent of each other, and their time
is in FFTs and compiled loops that release the GIL, so threads share them out. Each item
is computed whole by one thread and the results come back in the items' order: a call
gives the same result, to the bit, whatever its number of workers. The pools are kept
between calls; a process forked after a threaded call starts its own.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor
from typing import TypeVar

__all__ = ["resolved_workers", "thread_map"]

Item = TypeVar("Item")
Out = TypeVar("Out")

_pools: dict[int, ThreadPoolExecutor] = {}
_pools_lock = threading.Lock()


def _forget_pools() -> None:
    """In a forked child: the parent's pools have no threads there; start afresh."""
    global _pools_lock
    _pools.clear()
    _pools_lock = threading.Lock()


if hasattr(os, "register_at_fork"):  # a process forked after a threaded call
    os.register_at_fork(after_in_child=_forget_pools)


def resolved_workers(workers: int | None) -> int:
    """``workers``, or when None every core this process may run on, at most
    ``OMP_NUM_THREADS`` when that is set (the usual way to ask a process's libraries for
    fewer threads: the evaluation harness's worker processes run one thread each)."""
    if workers is not None:
        return workers
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not on Linux
        cores = os.cpu_count() or 1
    limit = os.environ.get("OMP_NUM_THREADS", "")
    if limit.isdigit() and int(limit) > 0:
        cores = min(cores, int(limit))
    return max(1, cores)


def thread_map(
    function: Callable[[Item], Out], items: Iterable[Item], workers: int | None
) -> list[Out]:
    """``[function(item) for item in items]`` on up to ``workers`` threads (all cores
    when None), in the items' order. One worker, or a call from inside a worker, runs in
    the calling thread."""
    items = list(items)
    count = min(resolved_workers(workers), len(items))
    if count <= 1 or threading.current_thread().name.startswith("o3d_spectral"):
        return [function(item) for item in items]
    with _pools_lock:
        pool = _pools.get(count)
        if pool is None:
            pool = _pools[count] = ThreadPoolExecutor(count, thread_name_prefix="o3d_spectral")
    return list(pool.map(function, items))
