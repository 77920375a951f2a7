"""The report of an evaluation run (``o3d-spectral report``): every table
(:mod:`~o3d_spectral.harness.tables`, written by :mod:`~o3d_spectral.harness.writers` as
Markdown, LaTeX booktabs and CSV) and plot (:mod:`~o3d_spectral.harness.figures`), and
``report.md`` joining them with the run's settings (from its sessions' records,
:func:`~o3d_spectral.harness.records.read_config`).
"""

from __future__ import annotations

import contextlib
import gc
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING

from o3d_spectral.harness.figures import (
    plot_convergence,
    plot_cumulative_errors,
    plot_success_vs_angle,
    plot_times,
)
from o3d_spectral.harness.records import load_results, read_config, result_files
from o3d_spectral.harness.row_checks import first_without
from o3d_spectral.harness.selection import TUNING_SPLIT, in_tuning_split
from o3d_spectral.harness.tables import (
    Table,
    ambiguity_table,
    bop_table,
    comparison_table,
    pairs_table,
    paper_table,
    spectral_methods,
    summary_table,
)
from o3d_spectral.harness.writers import to_markdown, write_table

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["make_report", "run_summary"]


#: Columns of a successful registration's row (:func:`~o3d_spectral.harness.metrics.
#: instance_metrics`) the tables and plots read; absent when every row failed.
_METRIC_COLUMNS = (
    "rotation_error_deg", "translation_error_m", "rotation_error_sym_deg",
    "translation_error_sym_m", "squared_translation_error_m2", "squared_rotation_error_rad2",
)


def _with_metric_columns(frame: pd.DataFrame) -> pd.DataFrame:
    """``frame`` with the metric columns a run whose rows all failed lacks (as NaN), so its
    tables show 0% success rather than fail."""
    missing = [c for c in _METRIC_COLUMNS if c not in frame]
    return frame.assign(**dict.fromkeys(missing, float("nan"))) if missing else frame


def _report_rows(results: Path) -> pd.DataFrame:
    """The run's rows (:func:`~o3d_spectral.harness.records.load_results`), every one with
    its ``success`` (``ValueError`` naming the file and line of one without), and the
    metric columns (:func:`_with_metric_columns`)."""
    frame = load_results(results)
    if "success" not in frame or frame["success"].isna().any():
        where = first_without(result_files(results), "success") or str(results)
        raise ValueError(f"{where}: not a results row: no 'success'; fix or remove that line")
    return _with_metric_columns(frame)


#: The summary's columns ``eval`` prints when it ends (:func:`run_summary`).
_RUN_SUMMARY_COLUMNS = ("suite", "method", "n", "success (%)", "median time (s)", "failed")


def _aligned(markdown: str) -> str:
    """A Markdown table (:func:`~o3d_spectral.harness.writers.to_markdown`) with its columns
    padded to one width, numbers right-aligned: readable as plain text too."""
    rows = [[cell.strip() for cell in line.strip()[1:-1].split("|")]
            for line in markdown.splitlines()]
    right = [cell.endswith(":") for cell in rows[1]]
    widths = [max(3, *(len(cell) for k, cell in enumerate(column) if k != 1))  # 1: ---
              for column in zip(*rows, strict=True)]
    rows[1] = ["-" * (w - 1) + (":" if r else "-") for w, r in zip(widths, right, strict=True)]
    lines = [" | ".join(cell.rjust(w) if r else cell.ljust(w)
                        for cell, w, r in zip(row, widths, right, strict=True))
             for row in rows]
    return "".join(f"| {line} |\n" for line in lines)


def run_summary(results: str | Path) -> str:
    """The success rate and median time of each method on each suite of a run, as the
    report's summary (:func:`~o3d_spectral.harness.tables.summary_table`) cut to those
    columns, its size and its failures: a Markdown table aligned as plain text (what
    ``o3d-spectral eval`` prints when it ends).

    Parameters
    ----------
    results : str or Path
        A run folder written by :func:`~o3d_spectral.harness.runner.run_eval`, or its
        ``results.jsonl``.
    """
    table = summary_table(_report_rows(Path(results)))
    columns = list(_RUN_SUMMARY_COLUMNS)
    cut = Table(table.name, table.caption, table.frame[columns],
                {c: table.formats[c] for c in columns})
    return _aligned(to_markdown(cut))


def _run_config(results: Path) -> dict:
    return read_config(results if results.is_dir() else results.parent)


def _versions(session: dict) -> str:
    """The package versions and commit of a session (runs before the versions had their
    own entry kept them in ``machine``)."""
    versions = session.get("versions") or session["machine"]
    names = {"python": "Python", "open3d": "Open3D", "numpy": "NumPy", "scipy": "SciPy"}
    names |= {"pyfftw": "pyFFTW", "o3d_spectral": "o3d-spectral"}
    text = ", ".join(f"{label} {versions[key]}" for key, label in names.items() if key in versions)
    if session.get("commit"):
        text += f" at commit {session['commit'][:12]}"
    return text


def _run_section(config: dict, frame: pd.DataFrame) -> str:
    sessions = config.get("sessions", [])
    if not sessions:
        return "Run settings unknown (no session records next to the results).\n"
    machine = sessions[-1]["machine"]
    seconds = sum(s["seconds"] for s in sessions)
    criteria = config["criteria"]
    lines = [
        f"* {len(frame)} registrations: {frame['method'].nunique()} methods on "
        f"{frame[['suite', 'index']].drop_duplicates().shape[0]} instances, voxel size "
        f"{1e3 * config['voxel_size']:g} mm, run seed {config['seed']}.",
        f"* Success: rotation ≤ {criteria['max_rotation_deg']:g} deg and translation ≤ "
        f"{1e3 * criteria['max_translation_m']:g} mm (symmetry-aware, at the object's centroid).",
        f"* Eval wall time: {seconds / 60:.1f} min in {len(sessions)} session(s), "
        f"{', '.join(str(s['workers']) for s in sessions)} worker(s), one thread each.",
        f"* Machine: {machine['cpu']}, {machine['cores']} cores, {machine['memory_gib']} GiB; "
        f"{machine['platform']}; {_versions(sessions[-1])}.",
    ]
    return "\n".join(lines) + "\n"


def _markdown_report(
    config: dict, frame: pd.DataFrame, tables: list[Table], figures: dict, prefix: str
) -> str:
    parts = ["## Run\n", _run_section(config, frame)]
    titles = {
        "table1": "Table 1 (paper layout)",
        "summary": "Success rate and time",
        "comparison": "Where spectral loses (automatic comparison)",
        "ambiguity": "What the views leave open",
        "summary_held_out": "Success rate and time off the tuning split",
        "bop": "BOP's average recall (AR)",
        "pairs": "Registration recall of scan pairs",
    }
    for table in tables:
        parts += [f"\n## {titles[table.name]}\n", f"{table.caption}\n", "\n" + to_markdown(table)]
    parts.append("\n## Plots\n")
    for title, path in figures.items():
        parts.append(f"\n**{title}**\n\n![{title}]({prefix}{path.name})\n")
    return "".join(parts)


def _figures(frame: pd.DataFrame, config: dict, spectral: list[str], out: Path) -> dict:
    """Draw every plot into ``out``; their paths by title."""
    plots: list[tuple[str, Callable[[Path], Path], str]] = [
        (
            "Success rate against initial rotation angle",
            lambda p: plot_success_vs_angle(frame, p),
            "success_vs_angle.png",
        ),
        (
            "Cumulative error curves",
            lambda p: plot_cumulative_errors(frame, p, thresholds=config.get("criteria")),
            "cumulative_errors.png",
        ),
        ("Time per registration", lambda p: plot_times(frame, p), "time.png"),
    ]
    figures = {title: plot(out / name) for title, plot, name in plots}
    convergence = plot_convergence(frame, {m: out / f"convergence_{m}.png" for m in spectral})
    return figures | {f"Convergence of {m}": path for m, path in convergence.items()}


def _held_out_summary(frame: pd.DataFrame, config: dict) -> Table | None:
    """The summary on the instances off the tuning split only, when a method of the run was
    tuned on it (its settings name a ``tuning_split``): every method on the same instances
    as the tuned one. None otherwise."""
    settings = {}
    for session in config.get("sessions", []):
        settings |= session.get("method_settings", {})
    tuned = sorted(m for m, s in settings.items() if s and "tuning_split" in s)
    if not tuned or not frame["method"].isin(tuned).any():
        return None
    held_out = frame[~frame["index"].map(in_tuning_split)]
    table = summary_table(held_out)
    caption = (
        f"As the summary, on the instances off the tuning split ({TUNING_SPLIT} is the "
        f"split) only, where {', '.join(tuned)} ran: every method on the same instances."
    )
    return Table("summary_held_out", caption, table.frame, table.formats)


@contextlib.contextmanager
def _collector_paused() -> Iterator[None]:
    """Pause Python's cyclic garbage collector while a report is made, and restore it after
    (reference counting frees memory as usual). Drawing makes hundreds of thousands of
    short-lived objects, and every few hundred of them the collector scanned every live
    object, the run's rows among them: a sixth of a report's time. The reference cycles of
    the closed figures are collected after."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


@_collector_paused()
def make_report(
    results: str | Path, out_dir: str | Path, *, link_prefix: str = ""
) -> dict[str, Path]:
    """Write every table and plot of a run into ``out_dir``, and ``report.md`` joining them.

    Parameters
    ----------
    results : str or Path
        A run folder written by :func:`~o3d_spectral.harness.runner.run_eval`, or its
        ``results.jsonl``.
    out_dir : str or Path
        Folder for the tables (``.md``, ``.tex``, ``.csv``), plots (``.png``) and
        ``report.md``; created if missing.
    link_prefix : str, optional
        Prepended to image links in ``report.md`` (when its text is pasted elsewhere).

    Returns
    -------
    dict of str to Path
        Every file written, by name (e.g. ``"table1.tex"``).
    """
    results = Path(results)
    frame = _report_rows(results)
    config = _run_config(results)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    spectral = spectral_methods(frame)
    summary = summary_table(frame)
    tables = [paper_table(frame), summary]
    if spectral:
        tables.append(comparison_table(summary, spectral))
    if "indistinguishable" in frame:
        tables.append(ambiguity_table(frame))
    condition = frame["condition"].astype(str)
    if condition.str.startswith("bop_").any():
        tables.append(bop_table(frame))
    if condition.str.startswith("pairs").any():
        tables.append(pairs_table(frame))
    held_out = _held_out_summary(frame, config)
    if held_out is not None:
        tables.append(held_out)
    written = [path for table in tables for path in write_table(table, out)]
    figures = _figures(frame, config, spectral, out)
    report = out / "report.md"
    report.write_text(_markdown_report(config, frame, tables, figures, link_prefix))
    return {path.name: path for path in [*written, *figures.values(), report]}
