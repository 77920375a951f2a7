"""Sub-command ``convert``: the real data written as benchmark folders that ``eval --bop``
and ``eval --pairs`` read (:mod:`o3d_spectral.harness.converters`)."""

from __future__ import annotations

import argparse
from pathlib import Path


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``convert`` (with its sub-commands ``ycbv`` and ``dragon``) on the
    ``o3d-spectral`` parser."""
    from o3d_spectral.cli import HelpFormatter

    parser = subparsers.add_parser(
        "convert",
        help="write the real data as benchmark folders (BOP layout, 3DMatch layout)",
        description=(
            "Write the original YCB-Video frame as a BOP dataset folder (eval --bop), or the "
            "bundled dragon scans as a 3DMatch scene folder (eval --pairs)."
        ),
        epilog=(
            "examples:\n"
            "  o3d-spectral convert ycbv originals out/bop_ycbv\n"
            "  o3d-spectral convert dragon out/dragon_3dmatch\n"
            "  o3d-spectral eval --pairs out/dragon_3dmatch --voxel-size 0.006 "
            "--out out/dragon_pairs"
        ),
    )
    layouts = parser.add_subparsers(dest="dataset", required=True, metavar="DATASET")
    ycbv = layouts.add_parser(
        "ycbv",
        help="the original YCB-Video frame as a BOP folder",
        description=(
            "Write the original YCB-Video frame (SOURCE/ycbv: classes.txt, LICENSE, "
            "models/<class>/points.xyz, 0000_000001/{scene.ply, K.txt, <class>_crop.ply, "
            "<class>_T_cam_from_model.txt} for 009_gelatin_box, 025_mug and 061_foam_brick) "
            "as a BOP folder: the depth image and the objects' visible masks (one pixel per "
            "point), the poses, the model clouds with normals (models_eval) and their "
            "screened Poisson surfaces, trimmed to 1 cm of the points (models, for VSD). "
            "Prints each surface's distances to its points (mm) and each object's visible "
            "pixels. The bundled o3d_spectral/datasets/bop_ycbv was written so."
        ),
        epilog="example:\n  o3d-spectral convert ycbv originals out/bop_ycbv",
        formatter_class=HelpFormatter,
    )
    ycbv.add_argument("source", metavar="SOURCE", type=Path,
                      help="folder of the originals (holding ycbv/)")
    ycbv.add_argument("out", metavar="OUT", type=Path,
                      help="BOP folder to write; its models, models_eval and test folders "
                      "are replaced")
    ycbv.set_defaults(func=ycbv_command, status=True)

    dragon = layouts.add_parser(
        "dragon",
        help="the bundled dragon scans as a 3DMatch scene folder",
        description=(
            "Write the eight bundled dragon scans (24 degrees apart on a turntable) as "
            "cloud_bin_0.ply .. cloud_bin_7.ply, with normals turned to the scanner, and "
            "gt.log / gt.info for every pair at most --max-step degrees apart."
        ),
        epilog="example:\n  o3d-spectral convert dragon out/dragon_3dmatch",
        formatter_class=HelpFormatter,
    )
    dragon.add_argument("out", metavar="OUT", type=Path, help="scene folder to write")
    dragon.add_argument("--max-step", type=int, default=72, metavar="DEG",
                        help="largest turn between the scans of a pair, degrees (the scans "
                        "are 24 apart; the default, 72: the pairs sharing 55%% or more of "
                        "their surface)")
    dragon.set_defaults(func=dragon_command, status=True)


def ycbv_command(args: argparse.Namespace) -> int:
    from o3d_spectral.cli import results
    from o3d_spectral.harness.converters import convert_ycbv

    for entry in convert_ycbv(args.source, args.out):
        stats = ", ".join(f"{k} {v:.3g}" for k, v in entry["stats"].items())
        print(f"{entry['class']} obj_{entry['object_id']:06d}: {stats}; "
              f"{entry['visible_pixels']} visible pixels, {entry['rendered_pixels']} rendered: "
              f"{entry['visible_fraction']:.2f}", file=results())
    print(f"wrote {args.out}", file=results())
    return 0


def dragon_command(args: argparse.Namespace) -> int:
    from o3d_spectral.cli import UsageError, results
    from o3d_spectral.harness.real import DRAGON_ANGLES, write_dragon_pairs

    steps = [b - a for a in DRAGON_ANGLES for b in DRAGON_ANGLES if b > a]
    if args.max_step < min(steps):
        raise UsageError(f"--max-step must be at least {min(steps)} degrees (the scans' "
                         f"step), got {args.max_step}")
    if args.out.exists() and not args.out.is_dir():
        raise ValueError(f"OUT {args.out} is a file, not a folder")
    print(f"wrote {write_dragon_pairs(args.out, args.max_step)}", file=results())
    return 0
