"""Independent work of one call spread over threads.

The global search's placements (and the sweep's batches of them), climbs, the ascent's
coarse starts and the confirmation's polishes are independent of each other, and their
time is in FFTs, compiled loops and Open3D's ICP, which release the GIL, so threads share
them out. Each item is computed whole by one thread and the results
come back in the items' order: a call gives the same result, to the bit, whatever its
number of workers. The pools are kept between calls; a process forked after a threaded
call starts its own.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from typing import TypeVar

__all__ = ["resolved_workers", "thread_map", "one_open3d_thread"]

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


class _Open3DThreads:
    """How many :func:`one_open3d_thread` blocks are open, and Open3D's thread count
    before the first of them opened."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.open = 0
        self.saved = 1


_open3d_threads = _Open3DThreads()


@contextmanager
def one_open3d_thread() -> Iterator[None]:
    """Open3D's own parallel loops limited to one thread while the block runs, in this
    thread and any other: its multi-threaded sums change the last bits of a result from
    run to run, and a result must repeat exactly. Blocks may overlap across threads (the
    confirmation's polishes run side by side): the limit holds until the last one closes,
    which restores the count the first one found."""
    import open3d as o3d  # here: the rest of this module serves layers free of Open3D

    state = _open3d_threads
    with state.lock:
        if state.open == 0:
            state.saved = o3d.utility.get_max_threads()
            o3d.utility.set_max_threads(1)
        state.open += 1
    try:
        yield
    finally:
        with state.lock:
            state.open -= 1
            if state.open == 0:
                o3d.utility.set_max_threads(state.saved)
