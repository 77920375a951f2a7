"""How a command stops early: Ctrl-C (SIGINT) and SIGTERM end it the same clean way, and a
reader that goes away (a closed pipe) ends it quietly.

Python turns SIGINT into ``KeyboardInterrupt``; :func:`sigterm_as_interrupt` turns SIGTERM
(``kill``, a batch scheduler's time limit, ``docker stop``) into :class:`Terminated`, a
``KeyboardInterrupt`` too, so that every path that keeps the work done so far on Ctrl-C
(eval's rows, a folder's claim released) runs on SIGTERM as well. :func:`stop_status` is
the line's word and the exit status: 130 and 143, the shell's ``128 + signal``. Imports
of C extensions run with both held (:func:`signals_held`): a stop meanwhile is raised
once they are loaded.
"""

from __future__ import annotations

import atexit
import contextlib
import importlib
import logging
import os
import signal
import sys
import threading
from collections.abc import Iterator
from types import ModuleType

from .constants import BROKEN_PIPE_STATUS

__all__ = ["BROKEN_PIPE_STATUS", "Terminated", "exit_after_stop", "import_whole",
           "quiet_broken_pipe", "sigterm_as_interrupt", "signals_held", "stop_cause",
           "stop_status"]


class Terminated(KeyboardInterrupt):
    """SIGTERM received: raised where the program is, as Ctrl-C raises
    ``KeyboardInterrupt``."""


def _raise_terminated(signum: int, frame: object) -> None:
    raise Terminated()


def _in_main_thread() -> bool:
    """Signals are delivered to the main thread only: handlers and masks go there."""
    return threading.current_thread() is threading.main_thread()


@contextlib.contextmanager
def sigterm_as_interrupt() -> Iterator[None]:
    """While the block runs (in the main thread), SIGTERM raises :class:`Terminated`;
    the previous handler is restored after."""
    if not _in_main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


@contextlib.contextmanager
def signals_held() -> Iterator[None]:
    """Hold SIGINT and SIGTERM while the block runs, then let a held one through: for
    imports of C extensions (NumPy's, Open3D's, a few tenths of a second), which one
    landing inside leaves half made (an ``ImportError``, and an exit status of 1 at the
    interpreter's exit whatever the command returned)."""
    if not _in_main_thread() or not hasattr(signal, "pthread_sigmask"):
        yield
        return
    held = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, held)


def import_whole(name: str) -> ModuleType:
    """Import the module ``name`` with the stops held (:func:`signals_held`)."""
    with signals_held():
        return importlib.import_module(name)


def stop_status(stop: KeyboardInterrupt) -> tuple[str, int]:
    """``("terminated", 143)`` for SIGTERM, ``("interrupted", 130)`` for Ctrl-C."""
    if isinstance(stop, Terminated):
        return "terminated", 128 + signal.SIGTERM
    return "interrupted", 128 + signal.SIGINT


def stop_cause(error: BaseException) -> KeyboardInterrupt | None:
    """The Ctrl-C or SIGTERM behind ``error``, if any: one that lands while a C extension
    is being imported comes back as ``ImportError("initialization failed")`` caused by
    it."""
    seen: BaseException | None = error
    while seen is not None:
        if isinstance(seen, KeyboardInterrupt):
            return seen
        seen = seen.__cause__ or seen.__context__
    return None


def exit_after_stop(code: int) -> None:
    """End the process with ``code`` when it is a stop's status (130, 143) once Python's
    exit handlers have run (multiprocessing's clean-up of the pool's semaphores, the
    log's flush) but before the extension modules are torn down: an Open3D call cut
    short by the stop leaves an allocation behind, and Open3D's leak check in that
    teardown would print its statistics to the standard output and turn the status into
    1. Other codes return."""
    if code not in (128 + signal.SIGINT, 128 + signal.SIGTERM):
        return
    logging.shutdown()
    atexit._run_exitfuncs()  # what sys.exit would run, short of the extensions' teardown
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(OSError, ValueError, AttributeError):
            stream.flush()
    os._exit(code)


def quiet_broken_pipe() -> int:
    """After a ``BrokenPipeError`` on the standard output: point descriptor 1 at the null
    device, so that the interpreter's last flush at exit does not fail again with a
    traceback, and return :data:`BROKEN_PIPE_STATUS`."""
    with contextlib.suppress(OSError, ValueError, AttributeError):
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, sys.stdout.fileno())
        os.close(null)
    return BROKEN_PIPE_STATUS
