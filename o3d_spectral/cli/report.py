"""Sub-command ``report``: tables and plots of an ``eval`` run."""

from __future__ import annotations

import argparse


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``report`` on the ``o3d-spectral`` parser."""
    parser = subparsers.add_parser(
        "report",
        help="tables (Markdown, LaTeX, CSV) and plots (PNG) of an eval run",
        description=(
            "Write the paper's Table 1, a per-suite success and time table and a comparison "
            "of each spectral method with the best other method (as .md, booktabs .tex and "
            ".csv), plots of success against initial angle, cumulative errors, time and "
            "convergence, and report.md joining them."
        ),
        epilog="example:\n  o3d-spectral report results/run --out results/run/report",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("results", metavar="RESULTS", help="eval run folder or its results.jsonl")
    parser.add_argument("--out", required=True, metavar="DIR", help="folder for tables and plots")
    parser.set_defaults(func=report_command, open3d=False)  # tables only: no Open3D import


def report_command(args: argparse.Namespace) -> int:
    from o3d_spectral.common.extras import require_modules

    require_modules("this command", "pandas", "matplotlib")
    from o3d_spectral.cli import results
    from o3d_spectral.harness.report import make_report

    written = make_report(args.results, args.out)
    print(f"wrote {len(written)} files to {args.out}: {', '.join(sorted(written))}",
          file=results())
    return 0
