"""Sub-command ``eval``: run registration methods on scene suites, BOP datasets or
3DMatch-layout scan pairs (resumable)."""

from __future__ import annotations

import argparse
import logging
import sys

from .arguments import seed

log = logging.getLogger(__name__)

EXAMPLES = (
    "examples:\n"
    "  o3d-spectral eval --suite suites/full suites/partial --workers 2 --out results/run\n"
    "  o3d-spectral eval --suite suites/full --methods spectral fpfh_ransac --limit 12 "
    "--out out/quick\n"
    "  o3d-spectral eval --suite suites/full --plugin my_methods --methods teaser --out "
    "results/run   # adds a method to a finished run\n"
    "  o3d-spectral eval --suite suites/full --cluster local --workers 2 --out results/run\n"
    "  o3d-spectral eval --suite suites/full --shard 0/2 --out /shared/run   # machine 1\n"
    "  o3d-spectral eval --suite suites/full --shard 1/2 --out /shared/run   # machine 2\n"
    "  o3d-spectral eval --bop data/ycbv --split test --scenes 48 49 --limit 20 "
    "--methods spectral_global fpfh_ransac --out results/ycbv\n"
    "  o3d-spectral eval --pairs data/3dmatch --voxel-size 0.05 --out results/3dmatch\n"
    "\n"
    "Run it again with the same --out to resume: done (instance, method) pairs are skipped.\n"
    "Several sessions may write one --out at once (shards, machines); report merges them.\n"
    "Methods: spectral, spectral_paper, spectral_global, icp_point_to_point, icp_point_to_plane,\n"
    "fpfh_ransac, fpfh_ransac_lean (its ICP on clouds thinned to half the voxel), fgr,\n"
    "fpfh_ransac_tuned (not on the tuning split, index % 4 == 0),\n"
    "kiss_matcher and small_gicp (pip install 'o3d-spectral[peers]'), and any a plugin\n"
    "registers (an unknown name lists them)."
)


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``eval`` on the ``o3d-spectral`` parser."""
    parser = subparsers.add_parser(
        "eval",
        help="run registration methods on scene suites, one results row per instance",
        description=(
            "Run every method on every instance of the suites (make-suite output), of a BOP "
            "dataset (--bop) or of 3DMatch-layout scan pairs (--pairs) and append "
            "one row per (instance, method) to OUT/results/SESSION.jsonl (the session's "
            "settings in OUT/sessions/SESSION.json); OUT/results.csv is the table of all "
            "sessions. Each worker runs one registration at a time on one thread."
        ),
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "--suite",
        nargs="+",
        action="extend",
        default=[],
        metavar="DIR",
        help="suite folder(s); repeatable",
    )
    _add_benchmark_arguments(parser)
    parser.add_argument(
        "--methods", nargs="+", metavar="NAME", help="methods to run (default: all registered)"
    )
    parser.add_argument(
        "--out", required=True, metavar="DIR", help="run folder (resumed if present)"
    )
    parser.add_argument(
        "--voxel-size",
        type=float,
        default=0.008,
        metavar="M",
        help="voxel edge shared by all methods, metres (default 0.008, the paper's)",
    )
    _add_executor_and_selection_arguments(parser)
    parser.add_argument("--seed", type=seed, default=0, help="run seed (default 0)")
    _add_success_and_plugin_arguments(parser)
    parser.add_argument("--quiet", dest="errors_only", action="store_true",
                        default=argparse.SUPPRESS, help=argparse.SUPPRESS)  # as -q, once its own
    parser.set_defaults(func=eval_command)


def _add_benchmark_arguments(parser: argparse.ArgumentParser) -> None:
    """``--bop`` with its split, scenes and objects, and ``--pairs``."""
    parser.add_argument(
        "--bop", metavar="DIR",
        help="a BOP-format dataset: every annotated object against its visible-mask crop "
        "and against the whole depth frame, scored also by BOP's VSD, MSSD, MSPD and AR",
    )
    parser.add_argument("--split", default="test", metavar="NAME",
                        help="with --bop: the split folder (default test)")
    parser.add_argument("--scenes", nargs="+", type=int, metavar="ID",
                        help="with --bop: only these scene ids")
    parser.add_argument("--objects", nargs="+", type=int, metavar="ID",
                        help="with --bop: only these object ids")
    parser.add_argument(
        "--pairs", metavar="DIR",
        help="a 3DMatch-layout folder (cloud_bin_*.ply, gt.log, gt.info), or a folder of "
        "such scenes; scored also by both registration recalls (RE < 15 deg and TE < 30 cm; "
        "RMSE under gt.info <= 20 cm, unavailable without gt.info)",
    )


def _instance_sets(args: argparse.Namespace) -> list:
    """The suites' folders and the benchmarks' instance sets the arguments name."""
    from o3d_spectral.cli import UsageError
    from o3d_spectral.harness.sets import bop_sets, pair_sets

    if not (args.suite or args.bop or args.pairs):
        raise UsageError("give --suite, --bop or --pairs")
    if args.bop is None and (args.scenes or args.objects or args.split != "test"):
        raise UsageError("--split, --scenes and --objects go with --bop")
    sets: list = list(args.suite)
    if args.bop is not None:
        sets += bop_sets(args.bop, args.split, scenes=args.scenes, objects=args.objects)
    if args.pairs is not None:
        pairs = pair_sets(args.pairs)
        for scene in pairs:
            if scene.information is None:
                log.warning("%s: no gt.info beside gt.log: its pairs are scored by the RE / TE "
                            "recall only, the RMSE recall is unavailable", scene.root)
        sets += pairs
    return sets


def _add_executor_and_selection_arguments(parser: argparse.ArgumentParser) -> None:
    """Where the registrations run (``--workers``, ``--cluster``) and which instances
    (``--limit``, ``--sample``, ``--shard``)."""
    parser.add_argument(
        "--workers",
        type=int,
        default=1,
        metavar="N",
        help="worker processes (default 1); with --cluster local, the cluster's workers",
    )
    parser.add_argument(
        "--cluster",
        metavar="ADDRESS",
        help="run on a Dask cluster: 'local' (a LocalCluster of --workers one-thread "
        "workers), a scheduler address (tcp://host:8786) or a scheduler file; needs "
        "pip install 'o3d-spectral[cluster]'",
    )
    chosen = parser.add_mutually_exclusive_group()
    chosen.add_argument(
        "--limit", type=int, metavar="N",
        help="only the first N instances of each suite (of the crops and of the frames "
        "of --bop, of each scene of --pairs)"
    )
    chosen.add_argument(
        "--sample",
        type=int,
        metavar="N",
        help="only N instances of each suite drawn at random (seeded by --seed)",
    )
    parser.add_argument(
        "--shard",
        metavar="I/N",
        help="only shard I of N of the instances (by a hash of each instance); N sessions "
        "with shards 0/N .. N-1/N, into the same --out, run each instance once",
    )


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

    from o3d_spectral.common.extras import require_modules

    require_modules("this command", "pandas", "tqdm")
    if args.cluster is not None:
        require_modules("eval --cluster", "distributed")
    from o3d_spectral.cli import UsageError, results, show_progress
    from o3d_spectral.cli.stops import stop_status
    from o3d_spectral.harness import SuccessCriteria, run_eval
    from o3d_spectral.harness.report import run_summary
    from o3d_spectral.harness.selection import parse_shard

    if args.shard is not None:
        try:
            parse_shard(args.shard)
        except ValueError as error:
            raise UsageError(str(error)) from None

    start = time.perf_counter()
    try:
        table = run_eval(
            _instance_sets(args),
            args.out,
            methods=args.methods,
            workers=args.workers,
            voxel_size=args.voxel_size,
            seed=args.seed,
            limit=args.limit,
            sample=args.sample,
            shard=args.shard,
            cluster=args.cluster,
            criteria=SuccessCriteria(
                max_rotation_deg=args.max_rotation_deg, max_translation_m=args.max_translation
            ),
            plugins=args.plugin,
            progress=show_progress(args),
        )
    except KeyboardInterrupt as stop:  # Ctrl-C or SIGTERM: the pool's workers are ended
        word, code = stop_status(stop)
        print(f"o3d-spectral eval: {word}; the rows done so far stay in {args.out} "
              "(run the same command again to resume)", file=sys.stderr)
        return code
    if table.stat().st_size:  # else no row: a shard with nothing to run
        print(run_summary(args.out), file=results())
    print(f"wrote {table} in {time.perf_counter() - start:.1f} s", file=results())
    return 0
