"""Command line entry point ``o3d-spectral``: one sub-command per task.

Each sub-command lives in its own module exposing ``add_parser(subparsers)``, which
registers the command and sets ``func`` (called with the parsed arguments, returns an
exit code). Heavy imports stay inside the commands so ``--help`` is instant.

Errors are handled once, in :func:`main`: a command raises and ``main`` prints one line
``o3d-spectral COMMAND: error: ...`` (the traceback too with ``-vv``) and returns the exit
code: 0 success, 1 a failed run (any exception while running), 2 a usage error (argparse's
own, or :class:`UsageError` from a command's checks of its options). A command that needs
an optional extra checks for it first (:func:`o3d_spectral.common.extras.require_modules`); a
missing module of an extra is reported on one line naming the extra, exit code 1. Stops
(:mod:`~o3d_spectral.cli.stops`): Ctrl-C 130 and SIGTERM 143 with one line, a reader of
the output gone 141 quietly.

Standard output is the command's result only: while a command runs, whatever C++ code
writes to file descriptor 1 (Open3D's log) goes to stderr, as do the package's log
records (``-v``: its progress at INFO, as it happens). On a terminal, a call running
longer than a couple of seconds also shows a status line on stderr (the time so far and
the latest progress message), erased when it ends; never in a pipe or a file.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import platform
import sys
import time
import traceback
from typing import NoReturn

from o3d_spectral.cli._output import (
    is_terminal,
    logging_to_stderr,
    results,
    stdout_for_results_only,
)
from o3d_spectral.cli.stops import (
    exit_after_stop,
    quiet_broken_pipe,
    signals_held,
    sigterm_as_interrupt,
    stop_cause,
    stop_status,
)
from o3d_spectral.common.extras import MissingExtraError, missing_extra

__all__ = ["COMMANDS", "UsageError", "build_parser", "is_terminal", "main", "program",
           "results", "show_progress", "versions"]

COMMANDS = ("register", "demo", "suite", "eval", "report", "convert", "servo", "reconstruct")
log = logging.getLogger(__name__)  # "o3d_spectral.cli", under the package logger


class UsageError(ValueError):
    """A bad option value found by a command's own checks before it runs: exit code 2, as
    argparse's usage errors (other exceptions exit 1). A ``ValueError``, so callers catching
    those still catch it."""


def versions() -> str:
    """``o3d-spectral X.Y.Z`` and the versions of its main dependencies, one per line."""
    from importlib import metadata

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


class Parser(argparse.ArgumentParser):
    """argparse's parser, whose ``--help`` reports a failed write (argparse drops it: the
    help lost in a closed pipe, and status 0)."""

    def print_help(self, file=None) -> None:
        (file or sys.stdout).write(self.format_help())


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(
        prog="o3d-spectral",
        description="Spectral point-cloud registration and 3D visual servoing for Open3D.",
        epilog="exit codes: 0 success, 1 the command failed, 2 a usage error, 130 / 143 "
        "stopped by Ctrl-C / SIGTERM, 141 the reader of the output went away",
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


def show_progress(args: argparse.Namespace) -> bool:
    """Whether a command shows a progress bar: on a terminal's stderr only (a bar's
    carriage-return frames would fill a log or a pipe), and not with ``-q``."""
    return not getattr(args, "errors_only", False) and is_terminal(sys.stderr)


def _log_level(args: argparse.Namespace) -> int:
    if args.errors_only:
        return logging.ERROR
    return {0: logging.WARNING, 1: logging.INFO}.get(args.verbose, logging.DEBUG)


#: What commands raise for bad input or a missing extra: shown by message alone.
_EXPECTED = (ValueError, OSError, MissingExtraError)


def _one_line(error: BaseException) -> str:
    """The error's message on one line; an unexpected kind of error also names its type."""
    text = error.args[0] if isinstance(error, KeyError) and error.args else error
    text = "; ".join(line.strip() for line in str(text).splitlines() if line.strip())
    if isinstance(error, _EXPECTED):
        return text
    kind = type(error).__name__
    return f"{kind}: {text}" if text else kind


def _fail(args: argparse.Namespace, error: Exception, code: int) -> int:
    if args.verbose >= 2:
        traceback.print_exception(error)
    # A module of an extra that a command imported without checking first: name the extra.
    error = missing_extra(error, "this command") or error
    hint = ""
    if args.verbose < 2 and not isinstance(error, _EXPECTED):
        hint = " (-vv shows the traceback)"
    print(f"o3d-spectral {args.command}: error: {_one_line(error)}{hint}", file=sys.stderr)
    return code


def _flush_results() -> None:
    """Flush the results (a full disk fails here, named, not at exit in a traceback)."""
    try:
        results().flush()
    except BrokenPipeError:
        raise  # the reader went away: a quiet end, not an error
    except OSError as error:
        raise OSError(f"could not write the results to the standard output "
                      f"({error.strerror or error})") from None


def status_label(args: argparse.Namespace) -> str | None:
    """The status line's label for a command that wants one (``status`` default set by
    the command), on a terminal, without ``-q``; else None."""
    if getattr(args, "status", False) and show_progress(args):
        return f"o3d-spectral {args.command}"
    return None


def program() -> NoReturn:
    """The ``o3d-spectral`` program (its script, ``python -m o3d_spectral.cli``):
    :func:`main` on ``sys.argv``, then exit with its status (at once after a stop:
    :func:`~o3d_spectral.cli.stops.exit_after_stop`)."""
    code = main()
    exit_after_stop(code)
    sys.exit(code)


def main(argv: list[str] | None = None) -> int:
    """Run ``o3d-spectral`` with ``argv`` (default ``sys.argv[1:]``); the exit code.

    Ctrl-C and SIGTERM end it cleanly at any moment (:mod:`~o3d_spectral.cli.stops`): one
    line, status 130 or 143; a reader of the standard output that goes away ends it
    quietly with status 141; a closed standard output is refused at once (status 1).
    """
    with sigterm_as_interrupt():
        try:
            return _main(argv)
        except KeyboardInterrupt as stop:  # before a command started (parsing, imports)
            return _stopped(None, stop)
        except ImportError as error:  # a stop while Open3D's C extension was imported
            stop = stop_cause(error)
            if stop is None:
                raise
            return _stopped(None, stop)
        except BrokenPipeError:  # --help or --version into a pipe closed early
            return quiet_broken_pipe()


def _stopped(command: str | None, stop: KeyboardInterrupt) -> int:
    word, code = stop_status(stop)
    print(f"o3d-spectral{f' {command}' if command else ''}: {word}", file=sys.stderr)
    return code


def _main(argv: list[str] | None) -> int:
    if sys.stdout is None:  # started with the standard output closed (>&-)
        print("o3d-spectral: error: the standard output is closed: nowhere to write the "
              "results (redirect it to a file or to /dev/null)", file=sys.stderr)
        return 1
    try:
        with signals_held():  # the commands' modules import NumPy: a stop waits for it
            parser = build_parser()
        args = parser.parse_args(argv)
    except SystemExit as exit_:  # --help, --version, or a usage error argparse printed
        sys.stdout.flush()  # a broken pipe shows here, not in the interpreter's last flush
        return exit_.code if isinstance(exit_.code, int) else int(exit_.code is not None)
    with stdout_for_results_only(), logging_to_stderr(
        _log_level(args), open3d=getattr(args, "open3d", True), status=status_label(args)
    ):
        log.debug("arguments: %s", {k: v for k, v in vars(args).items() if k != "func"})
        start = time.perf_counter()
        try:
            code = int(args.func(args) or 0)
            _flush_results()
        except UsageError as error:
            return _fail(args, error, 2)
        except KeyboardInterrupt as stop:
            return _stopped(args.command, stop)
        except BrokenPipeError:
            raise  # answered once the standard output is restored
        except Exception as error:
            stop = stop_cause(error)
            return _fail(args, error, 1) if stop is None else _stopped(args.command, stop)
        log.info("%s done in %.1f s", args.command, time.perf_counter() - start)
        return code
