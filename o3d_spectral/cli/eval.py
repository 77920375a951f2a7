"""Sub-command ``eval``: run registration methods on scene suites (resumable)."""

from __future__ import annotations

import argparse

EXAMPLES = (
    "examples:\n"
    "  o3d-spectral eval --suite suites/full suites/partial --workers 2 --out results/run\n"
    "  o3d-spectral eval --suite suites/full --methods spectral fpfh_ransac --limit 12 "
    "--out out/quick\n"
    "  o3d-spectral eval --suite suites/full --plugin my_methods --methods teaser --out "
    "results/run   # adds a method to a finished run\n"
    "\n"
    "Run it again with the same --out to resume: done (instance, method) pairs are skipped.\n"
    "Methods: spectral, spectral_paper, spectral_global, icp_point_to_point, icp_point_to_plane,\n"
    "fpfh_ransac, fgr, and any a plugin registers (an unknown name lists them)."
)


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``eval`` on the ``o3d-spectral`` parser."""
    parser = subparsers.add_parser(
        "eval",
        help="run registration methods on scene suites, one results row per instance",
        description=(
            "Run every method on every instance of the suites (make-suite output) and append "
            "one row per (instance, method) to OUT/results.jsonl; OUT/results.csv is the "
            "table. Each worker runs one registration at a time on one thread."
        ),
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "--suite",
        nargs="+",
        action="extend",
        required=True,
        metavar="DIR",
        help="suite folder(s); repeatable",
    )
    parser.add_argument(
        "--methods", nargs="+", metavar="NAME", help="methods to run (default: all registered)"
    )
    parser.add_argument(
        "--out", required=True, metavar="DIR", help="run folder (resumed if present)"
    )
    parser.add_argument(
        "--workers", type=int, default=1, metavar="N", help="worker processes (default 1)"
    )
    parser.add_argument(
        "--voxel-size",
        type=float,
        default=0.008,
        metavar="M",
        help="voxel edge shared by all methods, metres (default 0.008, the paper's)",
    )
    parser.add_argument(
        "--limit", type=int, metavar="N", help="only the first N instances of each suite"
    )
    parser.add_argument("--seed", type=int, default=0, help="run seed (default 0)")
    _add_success_and_plugin_arguments(parser)
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.set_defaults(func=eval_command)


def _add_success_and_plugin_arguments(parser: argparse.ArgumentParser) -> None:
    """The success thresholds and ``--plugin``."""
    parser.add_argument(
        "--max-rotation-deg",
        type=float,
        default=5.0,
        metavar="DEG",
        help="success threshold on the rotation error, degrees (default 5)",
    )
    parser.add_argument(
        "--max-translation",
        type=float,
        default=0.01,
        metavar="M",
        help="success threshold on the translation error, metres (default 0.01)",
    )
    parser.add_argument(
        "--plugin",
        nargs="+",
        action="extend",
        default=[],
        metavar="MODULE",
        help="module(s) to import first, e.g. one registering more methods",
    )


def eval_command(args: argparse.Namespace) -> int:
    import time

    from o3d_spectral.harness import SuccessCriteria, run_eval

    start = time.perf_counter()
    table = run_eval(
        args.suite,
        args.out,
        methods=args.methods,
        workers=args.workers,
        voxel_size=args.voxel_size,
        seed=args.seed,
        limit=args.limit,
        criteria=SuccessCriteria(
            max_rotation_deg=args.max_rotation_deg, max_translation_m=args.max_translation
        ),
        plugins=args.plugin,
        progress=not args.quiet,
    )
    print(f"wrote {table} in {time.perf_counter() - start:.1f} s")
    return 0
