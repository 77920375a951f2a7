"""Command line entry point ``o3d-spectral``: one sub-command per task.

Each sub-command lives in its own module exposing ``add_parser(subparsers)``, which
registers the command and sets ``func`` (called with the parsed arguments, returns an
exit code). Heavy imports stay inside the commands so ``--help`` is instant.
"""

from __future__ import annotations

import argparse
import importlib
import sys

COMMANDS = ("register", "demo", "suite", "eval", "report", "servo")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="o3d-spectral",
        description="Spectral point-cloud registration and 3D visual servoing for Open3D.",
    )
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in COMMANDS:
        importlib.import_module(f"o3d_spectral.cli.{name}").add_parser(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except (ValueError, FileNotFoundError) as error:
        print(f"o3d-spectral {args.command}: error: {error}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
