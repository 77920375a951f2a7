"""Sub-commands ``make-suite`` (generate a scene suite) and ``show-suite`` (save a picture)."""

from __future__ import annotations

import argparse

from .arguments import seed

# As o3d_spectral.synthetic.scenes.CONDITIONS, written out so that --help stays light.
CONDITIONS = ("full", "partial", "occluded", "cluttered")


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``make-suite`` and ``show-suite`` on the ``o3d-spectral`` parser."""
    make = subparsers.add_parser(
        "make-suite",
        help="generate a seeded scene suite (clouds in PLY, one manifest.json)",
        description=(
            "Generate N registration instances of one condition from the bundled YCB models "
            "and write them to DIR. The same seed gives byte-identical files."
        ),
        epilog=(
            "examples:\n"
            "  o3d-spectral make-suite partial --n 240 --seed 0 --out suites/partial\n"
            "  o3d-spectral make-suite full --n 120 --angle-range 0 90 --out suites/full_0_90"
        ),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    make.add_argument("condition", choices=CONDITIONS, help="scene condition")
    make.add_argument("--n", type=int, default=240, help="instances (default 240: 20 per object)")
    make.add_argument("--seed", type=seed, default=0, help="suite seed (default 0)")
    make.add_argument("--out", required=True, metavar="DIR", help="output folder")
    make.add_argument(
        "--angle-range",
        nargs=2,
        type=float,
        metavar=("MIN", "MAX"),
        help="initial rotation angle range in degrees (default: uniform over SO(3))",
    )
    make.add_argument(
        "--max-offset",
        type=float,
        default=0.1,
        metavar="M",
        help="largest initial displacement of the object centroid, metres (default 0.1)",
    )
    make.add_argument(
        "--workers", type=int, default=1, help="worker processes (output does not depend on it)"
    )
    make.add_argument("--quiet", dest="errors_only", action="store_true",
                      default=argparse.SUPPRESS, help=argparse.SUPPRESS)  # as -q, once its own
    make.set_defaults(func=make_suite_command)

    show = subparsers.add_parser(
        "show-suite",
        help="save a PNG of one suite instance (source, target, ground-truth alignment)",
        epilog="example:\n  o3d-spectral show-suite suites/partial --index 3 --out partial.png",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    show.add_argument("suite", metavar="SUITE_DIR", help="folder written by make-suite")
    show.add_argument("--index", type=int, default=0, help="instance index (default 0)")
    show.add_argument("--out", required=True, metavar="PNG", help="picture to write")
    show.set_defaults(func=show_suite_command)


def make_suite_command(args: argparse.Namespace) -> int:
    import time
    from pathlib import Path

    import numpy as np

    from o3d_spectral.cli import UsageError
    from o3d_spectral.common.extras import require_modules

    if Path(args.out).exists() and not Path(args.out).is_dir():  # before any work
        raise UsageError(f"--out {args.out}: a file, not a folder")
    require_modules("this command", "tqdm")
    from o3d_spectral.cli import results, show_progress
    from o3d_spectral.synthetic.instance import SceneOptions
    from o3d_spectral.synthetic.suite import make_suite

    angle_range = None if args.angle_range is None else tuple(np.deg2rad(args.angle_range))
    options = SceneOptions(angle_range=angle_range, max_offset=args.max_offset)
    start = time.perf_counter()
    path = make_suite(
        args.condition,
        args.n,
        args.seed,
        args.out,
        options=options,
        workers=args.workers,
        progress=show_progress(args),
    )
    seconds = time.perf_counter() - start
    print(f"wrote {args.n} {args.condition} instances to {path} in {seconds:.1f} s",
          file=results())
    return 0


def show_suite_command(args: argparse.Namespace) -> int:
    from o3d_spectral.common.extras import require_modules

    require_modules("this command", "matplotlib")
    from o3d_spectral.cli import UsageError, results
    from o3d_spectral.synthetic.suite import load_suite, save_instance_figure

    suite = load_suite(args.suite)
    if not 0 <= args.index < len(suite):
        raise UsageError(f"--index must be in [0, {len(suite) - 1}], got {args.index}")
    print(f"wrote {save_instance_figure(suite[args.index], args.out)}", file=results())
    return 0
