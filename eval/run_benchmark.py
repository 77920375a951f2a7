"""The full benchmark in one command: suites, eval with every method, report, docs.

Generates the four default suites when missing (``--n`` instances each, seed ``--seed``),
runs ``o3d-spectral eval`` with every registered method (resumes an interrupted run), writes
the tables and plots with ``o3d-spectral report`` into ``--figures``, and, with ``--docs``,
replaces the generated part of that Markdown file (between its ``BEGIN GENERATED`` and
``END GENERATED`` markers). The documentation's tables are written from the stored
summary instead: copy ``FIGURES/summary.csv`` to ``docs/data/suites_all_methods.csv``, note
the commit in ``docs/data/sources.json`` and run ``python tools/docs_figures.py``.

    python eval/run_benchmark.py --workers 2                    # the documented run
    python eval/run_benchmark.py --n 2 --suites-dir out/tiny/suites --out out/tiny/run \\
        --figures out/tiny/report --docs out/tiny/results.md    # a smoke test
"""

from __future__ import annotations

import argparse
import os
import shlex
import sys
import time
from pathlib import Path

from o3d_spectral.cli import main as cli
from o3d_spectral.harness.report import make_report
from o3d_spectral.synthetic.suite import MANIFEST, load_suite, make_suite

CONDITIONS = ("full", "partial", "occluded", "cluttered")
BEGIN, END = "<!-- BEGIN GENERATED", "<!-- END GENERATED -->"
ROOT = Path(__file__).resolve().parent.parent


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--n", type=int, default=240, help="instances per suite (default 240)")
    parser.add_argument("--seed", type=int, default=0, help="suite and run seed (default 0)")
    parser.add_argument("--workers", type=int, default=2, help="worker processes (default 2)")
    parser.add_argument("--methods", nargs="+", help="default: every registered method")
    parser.add_argument("--suites-dir", type=Path, default=ROOT / "suites")
    parser.add_argument("--out", type=Path, default=ROOT / "results" / "benchmark")
    parser.add_argument(
        "--figures",
        type=Path,
        default=ROOT / "docs" / "results",
        help="folder for the report's tables and plots",
    )
    parser.add_argument(
        "--docs",
        type=Path,
        help="a Markdown file whose generated part is replaced (default: none)",
    )
    args = parser.parse_args(argv)
    if args.n < 1:
        parser.error(f"--n must be >= 1, got {args.n}")
    return args


def ensure_suite(condition: str, folder: Path, *, n: int, seed: int, workers: int) -> float:
    """Make the suite unless ``folder`` holds one with this condition, size and seed;
    return the seconds spent."""
    if (folder / MANIFEST).is_file():
        suite = load_suite(folder)
        if (suite.condition, len(suite), suite.manifest["seed"]) == (condition, n, seed):
            return 0.0
        raise ValueError(
            f"{folder} holds a {suite.condition} suite of {len(suite)} instances with seed "
            f"{suite.manifest['seed']}, not {condition}/{n}/{seed}: move it or pass --suites-dir"
        )
    start = time.perf_counter()
    make_suite(condition, n, seed, folder, workers=workers)
    return time.perf_counter() - start


def fill_docs(docs: Path, generated: str) -> None:
    """Replace the text between the generated-part markers of ``docs``."""
    text = docs.read_text()
    if BEGIN not in text or END not in text:
        raise ValueError(f"{docs} has no '{BEGIN} ... {END}' markers")
    head, rest = text.split(BEGIN, 1)
    marker_line, _ = rest.split("\n", 1)
    _, tail = rest.split(END, 1)
    docs.write_text(f"{head}{BEGIN}{marker_line}\n{generated}\n{END}{tail}")


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    command = shlex.join(["python", "eval/run_benchmark.py", *(argv or sys.argv[1:])])
    folders = [args.suites_dir / c for c in CONDITIONS]
    suite_seconds = sum(
        ensure_suite(c, f, n=args.n, seed=args.seed, workers=args.workers)
        for c, f in zip(CONDITIONS, folders, strict=True)
    )
    eval_args = [
        "eval",
        "--suite",
        *map(str, folders),
        "--workers",
        str(args.workers),
        "--seed",
        str(args.seed),
        "--out",
        str(args.out),
    ]
    if args.methods:
        eval_args += ["--methods", *args.methods]
    start = time.perf_counter()
    if cli(eval_args) != 0:
        return 1
    eval_seconds = time.perf_counter() - start
    docs_folder = args.figures.parent if args.docs is None else args.docs.parent
    prefix = Path(os.path.relpath(args.figures, docs_folder)).as_posix() + "/"
    written = make_report(args.out, args.figures, link_prefix=prefix)
    generated = "\n".join(
        [
            f"Produced by `{command}` (suites: {suite_seconds:.0f} s to generate, 0 when "
            f"they existed; this eval session: {eval_seconds / 60:.1f} min). Tables as LaTeX "
            f"and CSV are next to the plots in [{prefix}]({prefix}).",
            "",
            written["report.md"].read_text(),
        ]
    )
    if args.docs is None:
        print(f"report in {args.figures}; for the documentation: copy its summary.csv to "
              "docs/data/suites_all_methods.csv and run python tools/docs_figures.py")
    else:
        fill_docs(args.docs, generated)
        print(f"wrote {args.docs}")
    print(f"wrote {len(written)} files in {args.figures}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
