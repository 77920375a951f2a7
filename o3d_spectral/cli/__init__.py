"""Command line entry point ``o3d-spectral``: one sub-command per task.

Each sub-command lives in its own module exposing ``add_parser(subparsers)``, which
registers the command and sets ``func`` (called with the parsed arguments, returns an
exit code). Heavy imports stay inside the commands so ``--help`` is instant.

Errors are handled once, in :func:`main`: a command raises and ``main`` prints one line
``o3d-spectral COMMAND: error: ...`` (the traceback too with ``-vv``) and returns the exit
code: 0 success, 1 a failed run (any exception while running), 2 a usage error (argparse's
own, or :class:`UsageError` from a command's checks of its options).

Standard output is the command's result only: while a command runs, whatever C++ code
writes to file descriptor 1 (Open3D's log) goes to stderr, as do the package's log
records (``-v``: its progress at INFO, as it happens). On a terminal, a call running
longer than a couple of seconds also shows a status line on stderr (the time so far and
the latest progress message), erased when it ends; never in a pipe or a file.
"""

from __future__ import annotations

import argparse
import contextlib
import ctypes
import importlib
import logging
import os
import platform
import shutil
import sys
import threading
import time
import traceback
from collections.abc import Iterator
from importlib import metadata
from typing import TextIO

COMMANDS = ("register", "demo", "suite", "eval", "report", "servo")
LOG_FORMAT = "o3d-spectral: %(levelname)s: %(message)s"
#: Seconds a command runs before its status line appears, and between redraws.
STATUS_DELAY, STATUS_INTERVAL = 2.0, 0.5
log = logging.getLogger(__name__)  # "o3d_spectral.cli", under the package logger


class UsageError(ValueError):
    """A bad option value found by a command's own checks before it runs: exit code 2, as
    argparse's usage errors (other exceptions exit 1). A ``ValueError``, so callers catching
    those still catch it."""


def versions() -> str:
    """``o3d-spectral X.Y.Z`` and the versions of its main dependencies, one per line."""
    import o3d_spectral

    lines = [f"o3d-spectral {o3d_spectral.__version__}"]
    for name in ("open3d", "numpy", "scipy"):
        try:
            lines.append(f"{name} {metadata.version(name)}")
        except metadata.PackageNotFoundError:
            lines.append(f"{name} not installed")
    lines.append(f"python {platform.python_version()}")
    return "\n".join(lines)


class _VersionAction(argparse.Action):
    """``--version`` (argparse's own version action would re-wrap the lines into one)."""

    def __init__(self, option_strings, dest=argparse.SUPPRESS, default=argparse.SUPPRESS,
                 help=None):
        super().__init__(option_strings, dest=dest, default=default, nargs=0, help=help)

    def __call__(self, parser, namespace, values, option_string=None):
        print(versions())
        parser.exit()


class HelpFormatter(argparse.HelpFormatter):
    """``--help`` that shows each option's default (unless its text already says it) and
    keeps the line breaks of a description or epilog written on several lines (the
    examples); a text on one line is wrapped to the terminal as usual."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help
        default = action.default
        shown = not (default is None or default is False or default is argparse.SUPPRESS
                     or (isinstance(default, (list, tuple)) and not default))
        if (text and action.option_strings and shown and "default" not in text
                and text is not argparse.SUPPRESS):
            text += " (default: %(default)s)"
        return text

    def _fill_text(self, text: str, width: int, indent: str) -> str:
        if "\n" in text:
            return "".join(indent + line for line in text.splitlines(keepends=True))
        return super()._fill_text(text, width, indent)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="o3d-spectral",
        description="Spectral point-cloud registration and 3D visual servoing for Open3D.",
        epilog="exit codes: 0 success, 1 the command failed, 2 a usage error",
        formatter_class=HelpFormatter,
    )
    parser.add_argument("--version", action=_VersionAction,
                        help="print the versions of o3d-spectral, Open3D, NumPy, SciPy, Python")
    # Global options come before COMMAND. dest "errors_only": a command's own option
    # with the same dest would overwrite it (argparse applies the sub-parser's defaults).
    verbosity = parser.add_mutually_exclusive_group()
    verbosity.add_argument("-v", "--verbose", action="count", default=0,
                           help="more messages on stderr: -v progress (INFO), -vv debugging "
                           "and the traceback of a failure (DEBUG)")
    verbosity.add_argument("-q", "--quiet", dest="errors_only", action="store_true",
                           help="errors only on stderr (also Open3D's warnings): no "
                           "progress bar or status line")
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in COMMANDS:
        importlib.import_module(f"o3d_spectral.cli.{name}").add_parser(subparsers)
    for command in subparsers.choices.values():
        command.formatter_class = HelpFormatter
    return parser


def is_terminal(stream: TextIO) -> bool:
    """Whether ``stream`` is a terminal (not a pipe, a file, or a captured stream)."""
    try:
        return stream.isatty()
    except (AttributeError, ValueError):  # no such method, or closed
        return False


def show_progress(args: argparse.Namespace) -> bool:
    """Whether a command shows a progress bar: on a terminal's stderr only (a bar's
    carriage-return frames would fill a log or a pipe), and not with ``-q``."""
    return not getattr(args, "errors_only", False) and is_terminal(sys.stderr)


def _log_level(args: argparse.Namespace) -> int:
    if args.errors_only:
        return logging.ERROR
    return {0: logging.WARNING, 1: logging.INFO}.get(args.verbose, logging.DEBUG)


def _flush_c_stdout() -> None:
    """Flush the C library's ``stdout`` buffer (what C++ code printed and not yet written)."""
    try:
        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError, TypeError):  # no C library found by that name
        pass


#: Where a running command writes its results: the standard output it was started with.
_results: TextIO | None = None


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
def _stdout_for_results_only() -> Iterator[None]:
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
    _results, sys.stdout = wrapper or saved, sys.stderr
    try:
        yield
    finally:
        _flush_c_stdout()
        if wrapper is not None:
            wrapper.close()  # flushed; the descriptor stays open (closefd=False)
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
    """Records on stderr, the status line (if any) erased first."""

    def __init__(self, stream: TextIO, status: StatusLine | None) -> None:
        super().__init__(stream)
        self.status = status

    def emit(self, record: logging.LogRecord) -> None:
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
def _logging_to_stderr(level: int, *, open3d: bool = True,
                       status: str | None = None) -> Iterator[None]:
    """Show the package logger's records from ``level`` up on stderr, and Open3D's messages
    from the matching level, while a command runs; restored afterwards, since ``main`` may
    be called several times in one process (tests, eval/run_benchmark.py). ``open3d``:
    False for a command that does not use Open3D (``report``: its import takes seconds).
    ``status``: the label of a :class:`StatusLine` to show meanwhile (on a terminal)."""
    if not open3d:
        with _package_logging(level, status):
            yield
        return
    import open3d as o3d

    saved = o3d.utility.get_verbosity_level()
    verbosity = o3d.utility.VerbosityLevel
    o3d.utility.set_verbosity_level({
        logging.ERROR: verbosity.Error, logging.WARNING: verbosity.Warning,
        logging.INFO: verbosity.Info, logging.DEBUG: verbosity.Debug,
    }[level])
    try:
        with _package_logging(level, status):
            yield
    finally:
        o3d.utility.set_verbosity_level(saved)


@contextlib.contextmanager
def _package_logging(level: int, status: str | None = None) -> Iterator[None]:
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


def _one_line(error: BaseException) -> str:
    """The error's message on one line; an unexpected kind of error also names its type."""
    text = error.args[0] if isinstance(error, KeyError) and error.args else error
    text = "; ".join(line.strip() for line in str(text).splitlines() if line.strip())
    if isinstance(error, (ValueError, OSError)):  # what commands raise for bad input
        return text
    kind = type(error).__name__
    return f"{kind}: {text}" if text else kind


def _fail(args: argparse.Namespace, error: Exception, code: int) -> int:
    if args.verbose >= 2:
        traceback.print_exception(error)
    hint = ""
    if args.verbose < 2 and not isinstance(error, (ValueError, OSError)):
        hint = " (-vv shows the traceback)"
    print(f"o3d-spectral {args.command}: error: {_one_line(error)}{hint}", file=sys.stderr)
    return code


def _status_label(args: argparse.Namespace) -> str | None:
    """The status line's label for a command that wants one (``status`` default set by
    the command), on a terminal, without ``-q``; else None."""
    if getattr(args, "status", False) and show_progress(args):
        return f"o3d-spectral {args.command}"
    return None


def main(argv: list[str] | None = None) -> int:
    """Run ``o3d-spectral`` with ``argv`` (default ``sys.argv[1:]``); the exit code."""
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exit_:  # --help, --version, or a usage error argparse printed
        return exit_.code if isinstance(exit_.code, int) else int(exit_.code is not None)
    with _stdout_for_results_only(), _logging_to_stderr(
        _log_level(args), open3d=getattr(args, "open3d", True), status=_status_label(args)
    ):
        log.debug("arguments: %s", {k: v for k, v in vars(args).items() if k != "func"})
        start = time.perf_counter()
        try:
            code = int(args.func(args) or 0)
        except UsageError as error:
            return _fail(args, error, 2)
        except Exception as error:
            return _fail(args, error, 1)
        log.info("%s done in %.1f s", args.command, time.perf_counter() - start)
        return code
