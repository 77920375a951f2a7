"""Command line entry point ``o3d-spectral``: one sub-command per task.

Each sub-command lives in its own module exposing ``add_parser(subparsers)``, which
registers the command and sets ``func`` (called with the parsed arguments, returns an
exit code). Heavy imports stay inside the commands so ``--help`` is instant.

Errors are handled once, in :func:`main`: a command raises and ``main`` prints one line
``o3d-spectral COMMAND: error: ...`` (the traceback too with ``-vv``) and returns the exit
code: 0 success, 1 a failed run (any exception while running), 2 a usage error (argparse's
own, or :class:`UsageError` from a command's checks of its options). A command that needs
an optional extra checks for it first (:func:`o3d_spectral._extras.require_modules`); a
missing module of an extra is reported on one line naming the extra, exit code 1.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import logging
import platform
import sys
import time
import traceback
from collections.abc import Iterator
from importlib import metadata

from o3d_spectral._extras import MissingExtraError, missing_extra

COMMANDS = ("register", "demo", "suite", "eval", "report", "servo")
LOG_FORMAT = "o3d-spectral: %(levelname)s: %(message)s"
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


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="o3d-spectral",
        description="Spectral point-cloud registration and 3D visual servoing for Open3D.",
        epilog="exit codes: 0 success, 1 the command failed, 2 a usage error",
    )
    parser.add_argument("--version", action=_VersionAction,
                        help="print the versions of o3d-spectral, Open3D, NumPy, SciPy, Python")
    # Global options come before COMMAND. dest "quiet" is taken by the commands' own --quiet
    # (no progress bar), which argparse would let overwrite this one.
    verbosity = parser.add_mutually_exclusive_group()
    verbosity.add_argument("-v", "--verbose", action="count", default=0,
                           help="more messages on stderr: -v progress (INFO), -vv debugging "
                           "and the traceback of a failure (DEBUG)")
    verbosity.add_argument("-q", "--quiet", dest="errors_only", action="store_true",
                           help="errors only on stderr (also Open3D's warnings)")
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in COMMANDS:
        importlib.import_module(f"o3d_spectral.cli.{name}").add_parser(subparsers)
    return parser


def _log_level(args: argparse.Namespace) -> int:
    if args.errors_only:
        return logging.ERROR
    return {0: logging.WARNING, 1: logging.INFO}.get(args.verbose, logging.DEBUG)


@contextlib.contextmanager
def _logging_to_stderr(level: int, *, open3d: bool = True) -> Iterator[None]:
    """Show the package logger's records from ``level`` up on stderr, and Open3D's messages
    from the matching level, while a command runs; restored afterwards, since ``main`` may
    be called several times in one process (tests, eval/run_benchmark.py). ``open3d``:
    False for a command that does not use Open3D (``report``: its import takes seconds)."""
    if not open3d:
        with _package_logging(level):
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
        with _package_logging(level):
            yield
    finally:
        o3d.utility.set_verbosity_level(saved)


@contextlib.contextmanager
def _package_logging(level: int) -> Iterator[None]:
    """The package logger's records from ``level`` up on stderr while the block runs."""
    package = logging.getLogger("o3d_spectral")
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter(LOG_FORMAT))
    saved = package.level, package.propagate
    package.addHandler(handler)
    package.setLevel(level)
    package.propagate = False  # printed once even if something configured the root logger
    try:
        yield
    finally:
        package.removeHandler(handler)
        package.setLevel(saved[0])
        package.propagate = saved[1]


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


def main(argv: list[str] | None = None) -> int:
    """Run ``o3d-spectral`` with ``argv`` (default ``sys.argv[1:]``); the exit code."""
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exit_:  # --help, --version, or a usage error argparse printed
        return exit_.code if isinstance(exit_.code, int) else int(exit_.code is not None)
    with _logging_to_stderr(_log_level(args), open3d=getattr(args, "open3d", True)):
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
