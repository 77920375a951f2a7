"""What a command writes where, while it runs: its results to the standard output it was
started with (:func:`results`), everything else to stderr (Open3D's log, whether printed
by its Python module through ``sys.stdout`` or by C++ to file descriptor 1), the package
logger's records on stderr, and on a terminal a :class:`StatusLine` fed by them. Open3D's
lines and the package's records never share a line (:class:`WholeLines`)."""

from __future__ import annotations

import contextlib
import ctypes
import logging
import os
import shutil
import sys
import threading
import time
from collections.abc import Iterator
from typing import TextIO

from o3d_spectral.cli.constants import STATUS_DELAY, STATUS_INTERVAL
from o3d_spectral.cli.stops import import_whole

LOG_FORMAT = "o3d-spectral: %(levelname)s: %(message)s"


def is_terminal(stream: TextIO) -> bool:
    """Whether ``stream`` is a terminal (not a pipe, a file, or a captured stream)."""
    try:
        return stream.isatty()
    except (AttributeError, ValueError):  # no such method, or closed
        return False


def _flush_c_stdout() -> None:
    """Flush the C library's ``stdout`` buffer (what C++ code printed and not yet written)."""
    try:
        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError, TypeError):  # no C library found by that name
        pass


#: Where a running command writes its results: the standard output it was started with.
_results: TextIO | None = None
#: Held while a whole line is written to stderr (:class:`WholeLines`, the log handler).
_stderr_lock = threading.RLock()


class WholeLines:
    """A text stream writing to ``stream`` only whole lines, each thread's apart.

    Open3D's Python module prints a message and its newline in two writes, from whichever
    thread logs: another thread's text written between them (a log record, another
    Open3D message) would end up on the message's line. Each thread's text is kept
    until it ends a line; whole lines are written holding the lock the package's log
    handler holds too. :meth:`flush` writes the calling thread's unfinished line (and
    :meth:`drain` every thread's).
    """

    def __init__(self, stream: TextIO) -> None:
        self.stream = stream
        self._pending: dict[int, str] = {}

    def write(self, text: str) -> int:
        key = threading.get_ident()
        pending = self._pending.pop(key, "") + text
        end = pending.rfind("\n") + 1
        if end:
            with _stderr_lock:
                self.stream.write(pending[:end])
        if end < len(pending):
            self._pending[key] = pending[end:]
        return len(text)

    def flush(self) -> None:
        rest = self._pending.pop(threading.get_ident(), "")
        with _stderr_lock:
            self.stream.write(rest)
            self.stream.flush()

    def drain(self) -> None:
        """Write every thread's unfinished line, each ended."""
        with _stderr_lock:
            for key in list(self._pending):
                self.stream.write(self._pending.pop(key) + "\n")
            self.stream.flush()

    def __getattr__(self, name: str) -> object:  # encoding, fileno, isatty, ...
        return getattr(self.stream, name)


def results() -> TextIO:
    """The stream a command writes its results to: the standard output ``main`` was called
    with (``sys.stdout`` points to stderr while a command runs: Open3D prints its log
    through it)."""
    return sys.stdout if _results is None else _results


def _writes_to(stream: TextIO, fd: int) -> bool:
    try:
        return stream.fileno() == fd
    except (AttributeError, OSError, ValueError):  # a captured stream has no descriptor
        return False


@contextlib.contextmanager
def stdout_for_results_only() -> Iterator[None]:
    """While the block runs, what is written to stdout goes to stderr, by Python code
    (``sys.stdout``: Open3D's Python module prints its log through it) or by C code (file
    descriptor 1), and :func:`results` is the standard output: it holds the command's
    results only."""
    global _results
    if _results is not None or sys.stdout is None or sys.stderr is None:
        yield  # a command run by a command (already so), or no standard streams
        return
    saved = sys.stdout
    sys.stdout.flush()
    sys.stderr.flush()
    try:
        real: int | None = os.dup(1)
    except OSError:  # no descriptor 1: nothing to keep apart at that level
        real = None
    if real is not None:
        try:
            os.dup2(2, 1)
        except OSError:  # no descriptor 2: leave descriptor 1 as it is
            os.close(real)
            real = None
    wrapper = None
    if real is not None and _writes_to(saved, 1):  # the results go to the real one
        line_buffered = getattr(saved, "line_buffering", False)
        wrapper = open(real, "w", buffering=1 if line_buffered else -1,  # noqa: SIM115
                       encoding=saved.encoding, errors=saved.errors, closefd=False)
    lines = WholeLines(sys.stderr)
    _results, sys.stdout = wrapper or saved, lines
    try:
        yield
    finally:
        lines.drain()
        _flush_c_stdout()
        if wrapper is not None:  # flushed; the descriptor stays open (closefd=False)
            with contextlib.suppress(OSError):  # a full disk: main reported it already
                wrapper.close()
        if real is not None:
            os.dup2(real, 1)
            os.close(real)
        sys.stdout, _results = saved, None


class StatusLine:
    """One line on a terminal, rewritten in place: ``LABEL: 12 s; MESSAGE``, the time
    since it was created and the latest message given (:attr:`message`). It appears only
    once ``delay`` seconds have passed, is redrawn every ``interval`` seconds by a
    background thread, and is erased by :meth:`erase` (before other output is written:
    hold :attr:`lock` meanwhile) and by :meth:`stop`.

    Parameters
    ----------
    stream : text stream
        A terminal (the caller checks).
    label : str
    delay, interval : float
        Seconds.
    """

    def __init__(self, stream: TextIO, label: str, *, delay: float = 2.0,
                 interval: float = 0.5) -> None:
        self.stream, self.label = stream, label
        self.delay, self.interval = delay, interval
        self.message = "starting"
        self.lock = threading.RLock()
        self._shown = False
        self._start = time.perf_counter()
        self._stopped = threading.Event()
        self._thread = threading.Thread(target=self._run, name="o3d-spectral status",
                                        daemon=True)

    def start(self) -> StatusLine:
        """Start the thread drawing the line; ``self``."""
        self._thread.start()
        return self

    def _run(self) -> None:
        if self._stopped.wait(self.delay):
            return
        while not self._stopped.is_set():
            self.draw()
            self._stopped.wait(self.interval)

    def text(self) -> str:
        """The line as drawn now, cut to the terminal's width."""
        elapsed = time.perf_counter() - self._start
        line = f"{self.label}: {elapsed:.0f} s; {self.message}"
        return line[:max(shutil.get_terminal_size().columns - 1, 20)]

    def draw(self) -> None:
        """Write the line over the previous one."""
        with self.lock:
            if self._stopped.is_set():
                return
            self.stream.write("\r" + self.text() + "\x1b[K")
            self.stream.flush()
            self._shown = True

    def erase(self) -> None:
        """Erase the line if it is shown (the next draw writes it again)."""
        with self.lock:
            if self._shown:
                self.stream.write("\r\x1b[K")
                self.stream.flush()
                self._shown = False

    def stop(self) -> None:
        """Stop the thread and erase the line."""
        with self.lock:
            self._stopped.set()
        if self._thread.is_alive():
            self._thread.join()
        self.erase()


class _StderrHandler(logging.StreamHandler):
    """Records on stderr, each on a line of its own: after what C code printed to stdout
    so far (its buffer flushed), never inside a line Open3D is printing
    (:class:`WholeLines`), the status line (if any) erased first."""

    def __init__(self, stream: TextIO, status: StatusLine | None) -> None:
        super().__init__(stream)
        self.status = status

    def emit(self, record: logging.LogRecord) -> None:
        _flush_c_stdout()
        with _stderr_lock:
            if self.status is None:
                super().emit(record)
                return
            with self.status.lock:
                self.status.erase()
                super().emit(record)


class _StatusFeed(logging.Handler):
    """Gives the status line each progress record's message (INFO and above)."""

    def __init__(self, status: StatusLine) -> None:
        super().__init__(logging.INFO)
        self.status = status

    def emit(self, record: logging.LogRecord) -> None:
        lines = record.getMessage().strip().splitlines()
        self.status.message = lines[0] if lines else ""


@contextlib.contextmanager
def logging_to_stderr(level: int, *, open3d: bool = True,
                       status: str | None = None) -> Iterator[None]:
    """Show the package logger's records from ``level`` up on stderr, and Open3D's messages
    from the matching level, while a command runs; restored afterwards, since ``main`` may
    be called several times in one process (tests, eval/run_benchmark.py). ``open3d``:
    False for a command that does not use Open3D (``report``: its import takes seconds).
    ``status``: the label of a :class:`StatusLine` to show meanwhile (on a terminal)."""
    if not open3d:
        with package_logging(level, status):
            yield
        return
    o3d = import_whole("open3d")  # a stop meanwhile is raised once it is loaded

    saved = o3d.utility.get_verbosity_level()
    verbosity = o3d.utility.VerbosityLevel
    o3d.utility.set_verbosity_level({
        logging.ERROR: verbosity.Error, logging.WARNING: verbosity.Warning,
        logging.INFO: verbosity.Info, logging.DEBUG: verbosity.Debug,
    }[level])
    try:
        with package_logging(level, status):
            yield
    finally:
        o3d.utility.set_verbosity_level(saved)


@contextlib.contextmanager
def package_logging(level: int, status: str | None = None) -> Iterator[None]:
    """The package logger's records from ``level`` up on stderr while the block runs, and
    with ``status`` a status line labelled so fed by its records from INFO up."""
    package = logging.getLogger("o3d_spectral")
    line = (StatusLine(sys.stderr, status, delay=STATUS_DELAY, interval=STATUS_INTERVAL)
            if status else None)
    handler = _StderrHandler(sys.stderr, line)
    handler.setFormatter(logging.Formatter(LOG_FORMAT))
    handler.setLevel(level)
    handlers: list[logging.Handler] = [handler] + ([_StatusFeed(line)] if line else [])
    saved = package.level, package.propagate
    for each in handlers:
        package.addHandler(each)
    package.setLevel(min(level, logging.INFO) if line else level)
    package.propagate = False  # printed once even if something configured the root logger
    if line is not None:
        line.start()
    try:
        yield
    finally:
        if line is not None:
            line.stop()
        for each in handlers:
            package.removeHandler(each)
        package.setLevel(saved[0])
        package.propagate = saved[1]
