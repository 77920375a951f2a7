"""Tables and plots of an evaluation run (``o3d-spectral report``).

Tables (each as Markdown, LaTeX booktabs and CSV):

* ``table1``: the paper's Table 1, mean squared translation (m^2) and rotation (rad^2)
  errors per method, columns C-1 (full), C-2 (partial), C-3 (cluttered), then the other
  suites;
* ``summary``: per suite and method, success rate, median errors over the successes,
  median and 90th-percentile time;
* ``comparison``: each spectral method against the most successful other method, suite
  by suite, with a plain verdict (where spectral loses).

Plots (PNG): success rate against the initial rotation angle, cumulative error curves,
time per method, and for each spectral method its convergence curves (error against
iteration, the paper's Fig. 2 and 4). All errors are the symmetry-aware ones; translation
errors are measured at the object's centroid (:mod:`o3d_spectral.harness.metrics`).
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from o3d_spectral.harness._optional import require
from o3d_spectral.harness.methods import method_names
from o3d_spectral.harness.runner import CONFIG_FILE, CURVE_COLUMNS, load_results

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["PAPER_CONDITIONS", "Table", "make_report", "paper_table", "summary_table"]

#: Columns of the paper's Table 1.
PAPER_CONDITIONS = {"full": "C-1", "partial": "C-2", "cluttered": "C-3"}
ANGLE_BINS_DEG = np.arange(0.0, 181.0, 20.0)
_MAX_CURVES = 40  # instance curves drawn per panel (the median uses all)
_FLOOR = 1e-3  # smallest error drawn on log axes (deg, mm)


@dataclass(frozen=True)
class Table:
    """A result table: numbers in ``frame``, how to print each column in ``formats``.

    Attributes
    ----------
    name : str
        File stem.
    caption : str
    frame : pandas.DataFrame
        Raw values (written as they are to CSV).
    formats : dict of str to str
        Per column: ``"text"``, ``"int"``, ``"pct"`` (a fraction shown in percent),
        ``"f1"``, ``"f2"``, ``"f3"`` (fixed decimals) or ``"sci"``.
    """

    name: str
    caption: str
    frame: pd.DataFrame
    formats: dict[str, str]


# ---------------------------------------------------------------------------- ordering


def _method_order(frame: pd.DataFrame) -> list[str]:
    present = list(dict.fromkeys(frame["method"]))
    known = [m for m in method_names() if m in present]
    return known + sorted(m for m in present if m not in known)


def _suite_order(frame: pd.DataFrame) -> list[tuple[str, str]]:
    """(suite, condition) pairs: C-1, C-2, C-3 first, then the others by name."""
    pairs = frame[["suite", "condition"]].drop_duplicates().itertuples(index=False)
    rank = {condition: k for k, condition in enumerate(PAPER_CONDITIONS)}
    return sorted(pairs, key=lambda p: (rank.get(p[1], len(rank)), p[0]))


def _suite_label(suite: str, condition: str) -> str:
    return f"{PAPER_CONDITIONS[condition]} ({suite})" if condition in PAPER_CONDITIONS else suite


def _spectral_methods(frame: pd.DataFrame) -> list[str]:
    """Methods that reported convergence curves (iterative spectral variants)."""
    if CURVE_COLUMNS[0] not in frame:
        return []
    has_curve = frame[CURVE_COLUMNS[0]].map(lambda c: isinstance(c, list) and len(c) > 0)
    return [m for m in _method_order(frame) if has_curve[frame["method"] == m].any()]


# ---------------------------------------------------------------------------- tables


def paper_table(frame: pd.DataFrame) -> Table:
    """The paper's Table 1: mean squared symmetry-aware errors per method and suite."""
    pandas = require("pandas")
    suites = _suite_order(frame)
    rows = []
    for method in _method_order(frame):
        for column, label in (
            ("squared_translation_error_m2", "translation (m²)"),
            ("squared_rotation_error_rad2", "rotation (rad²)"),
        ):
            row = {"method": method, "error": label}
            for suite, condition in suites:
                cell = frame[(frame["method"] == method) & (frame["suite"] == suite)]
                row[_suite_label(suite, condition)] = cell[column].mean()
            rows.append(row)
    result = pandas.DataFrame(rows)
    formats = {"method": "text", "error": "text"} | {c: "sci" for c in result.columns[2:]}
    caption = (
        "Mean squared error over instances (the paper's Table 1): translation at the "
        "object's centroid in m², rotation in rad², both symmetry-aware; runs that raised "
        "an error are left out (see `failed` in the summary)."
    )
    return Table("table1", caption, result, formats)


def summary_table(frame: pd.DataFrame) -> Table:
    """Per suite and method: success rate, median errors over successes, time."""
    pandas = require("pandas")
    rows = []
    for suite, condition in _suite_order(frame):
        for method in _method_order(frame):
            runs = frame[(frame["suite"] == suite) & (frame["method"] == method)]
            if runs.empty:
                continue
            wins = runs[runs["success"].astype(bool)]
            failed = runs["error"].notna().sum() if "error" in runs else 0
            open_view = _flagged(runs).sum()
            rows.append(
                {
                    "suite": _suite_label(suite, condition),
                    "method": method,
                    "n": len(runs),
                    "success (%)": runs["success"].astype(bool).mean(),
                    "rotation error (deg)": wins["rotation_error_sym_deg"].median(),
                    "translation error (mm)": 1e3 * wins["translation_error_sym_m"].median(),
                    "median time (s)": runs["time_s"].median(),
                    "p90 time (s)": runs["time_s"].quantile(0.9),
                    "failed": failed,
                    "indistinguishable": open_view,
                }
            )
    result = pandas.DataFrame(rows)
    formats = {
        "suite": "text",
        "method": "text",
        "n": "int",
        "success (%)": "pct",
        "rotation error (deg)": "f2",
        "translation error (mm)": "f2",
        "median time (s)": "f3",
        "p90 time (s)": "f3",
        "failed": "int",
        "indistinguishable": "int",
    }
    caption = (
        "Success (symmetry-aware rotation and translation errors within the thresholds), "
        "median errors over the successful runs only, wall time per registration (one "
        "thread); `failed`: runs that raised an error (counted as failures); "
        "`indistinguishable`: failures whose pose fits the observed points as well as the "
        "ground truth does (`o3d_spectral.harness.metrics.indistinguishable`)."
    )
    return Table("summary", caption, result, formats)


def _flagged(runs: pd.DataFrame) -> pd.Series:
    """Per run: a failure whose pose fits the observation as well as the truth."""
    if "indistinguishable" not in runs:
        return require("pandas").Series(False, index=runs.index)
    return runs["indistinguishable"].map(lambda v: v is True or v == 1.0).astype(bool)


def ambiguity_table(frame: pd.DataFrame) -> Table:
    """Per suite: instances on which some method returned a wrong pose that fits the
    observed points as well as the ground truth (an open view)."""
    pandas = require("pandas")
    rows = []
    for suite, condition in _suite_order(frame):
        runs = frame[frame["suite"] == suite]
        flagged = runs[_flagged(runs)]
        instances, open_views = runs["index"].nunique(), flagged["index"].nunique()
        rows.append(
            {
                "suite": _suite_label(suite, condition),
                "instances": instances,
                "open views": open_views,
                "open (%)": open_views / instances,
                "methods flagging": flagged["method"].nunique(),
            }
        )
    result = pandas.DataFrame(rows)
    formats = {"suite": "text", "instances": "int", "open views": "int"}
    formats |= {"open (%)": "pct", "methods flagging": "int"}
    caption = (
        "`open views`: instances on which at least one method returned a wrong pose "
        "(outside the success thresholds) that explains at least 99% as many observed "
        "points as the ground truth does, within 5 mm of the model's surface, with at "
        "least the truth's share of its sensor-facing points, less 1%, within 5 mm of an "
        "observed point (`indistinguishable` in the summary counts them per method). The "
        "observed points cannot tell that pose from the truth: whether a method succeeds "
        "there depends on which of equally good poses it returns. Found by the methods' "
        "own mistakes, so a lower bound on how many views are open."
    )
    return Table("ambiguity", caption, result, formats)


def comparison_table(summary: Table, spectral: list[str]) -> Table:
    """Each spectral method against the most successful non-spectral method, per suite."""
    pandas = require("pandas")
    data = summary.frame
    rows = []
    for suite in dict.fromkeys(data["suite"]):
        here = data[data["suite"] == suite]
        others = here[~here["method"].isin(spectral)]
        if others.empty:
            continue
        best = others.loc[others["success (%)"].idxmax()]
        for method in spectral:
            mine = here[here["method"] == method]
            if mine.empty:
                continue
            mine = mine.iloc[0]
            delta = mine["success (%)"] - best["success (%)"]
            rows.append(
                {
                    "suite": suite,
                    "method": method,
                    "success (%)": mine["success (%)"],
                    "best other": best["method"],
                    "its success (%)": best["success (%)"],
                    "median time (s)": mine["median time (s)"],
                    "its median time (s)": best["median time (s)"],
                    "verdict": "loses" if delta < 0 else ("ties" if delta == 0 else "wins"),
                }
            )
    result = pandas.DataFrame(rows)
    formats = {c: "text" for c in ("suite", "method", "best other", "verdict")}
    formats |= {"success (%)": "pct", "its success (%)": "pct"}
    formats |= {"median time (s)": "f3", "its median time (s)": "f3"}
    caption = (
        "Each spectral method against the most successful other method of the suite; "
        "the verdict is on the success rate alone."
    )
    return Table("comparison", caption, result, formats)


def _cell(value, kind: str, *, latex: bool) -> str:
    if kind == "text":
        return _tex_text(str(value)) if latex else str(value)
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "--" if latex else "–"
    if kind == "int":
        return f"{int(value)}"
    if kind == "pct":
        return f"{100 * value:.1f}"
    if kind == "sci":
        mantissa, exponent = f"{value:.2e}".split("e")
        return rf"${mantissa}\times10^{{{int(exponent)}}}$" if latex else f"{value:.2e}"
    return f"{value:.{int(kind[1])}f}"


def _tex_text(text: str) -> str:
    """Plain text (Markdown code quotes dropped) made safe for LaTeX."""
    for plain, tex in (("`", ""), ("_", r"\_"), ("%", r"\%"), ("²", "$^2$"), ("≤", "$\\le$")):
        text = text.replace(plain, tex)
    return text


def to_markdown(table: Table) -> str:
    """The table as a GitHub Markdown table (numbers right-aligned)."""
    columns = list(table.frame.columns)
    align = ["---" if table.formats[c] == "text" else "---:" for c in columns]
    lines = ["| " + " | ".join(columns) + " |", "| " + " | ".join(align) + " |"]
    for row in table.frame.itertuples(index=False):
        cells = [_cell(v, table.formats[c], latex=False) for c, v in zip(columns, row, strict=True)]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def to_latex(table: Table) -> str:
    """The table as a LaTeX ``table`` with a booktabs ``tabular`` (``\\usepackage{booktabs}``)."""
    columns = list(table.frame.columns)
    spec = "".join("l" if table.formats[c] == "text" else "r" for c in columns)
    body = [
        " & ".join(
            _cell(v, table.formats[c], latex=True) for c, v in zip(columns, row, strict=True)
        )
        + r" \\"
        for row in table.frame.itertuples(index=False)
    ]
    return "\n".join(
        [
            r"\begin{table}[t]",
            r"\centering",
            rf"\caption{{{_tex_text(table.caption)}}}",
            rf"\label{{tab:{table.name}}}",
            rf"\begin{{tabular}}{{{spec}}}",
            r"\toprule",
            " & ".join(_tex_text(c) for c in columns) + r" \\",
            r"\midrule",
            *body,
            r"\bottomrule",
            r"\end{tabular}",
            r"\end{table}",
            "",
        ]
    )


def write_table(table: Table, out_dir: Path) -> list[Path]:
    """Write ``<name>.md``, ``<name>.tex`` and ``<name>.csv`` into ``out_dir``."""
    paths = [out_dir / f"{table.name}.{ext}" for ext in ("md", "tex", "csv")]
    paths[0].write_text(to_markdown(table))
    paths[1].write_text(to_latex(table))
    table.frame.to_csv(paths[2], index=False)
    return paths


# ---------------------------------------------------------------------------- plots


def _pyplot():
    matplotlib = require("matplotlib")
    matplotlib.use("Agg")
    return require("matplotlib.pyplot")


def _colours(frame: pd.DataFrame) -> dict[str, str]:
    return {m: f"C{k % 10}" for k, m in enumerate(_method_order(frame))}


def _panels(frame: pd.DataFrame, plt, *, rows: int = 1, height: float = 3.2):
    suites = _suite_order(frame)
    fig, axes = plt.subplots(
        rows, len(suites), figsize=(3.6 * len(suites), height * rows), squeeze=False
    )
    for ax, (suite, condition) in zip(axes[0], suites, strict=True):
        ax.set_title(_suite_label(suite, condition), fontsize=10)
    return fig, axes, suites


def _save(fig, plt, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def plot_success_vs_angle(frame: pd.DataFrame, path: Path) -> Path:
    """Success rate (%) per bin of the initial rotation angle (0-180 degrees, 20-degree bins)."""
    plt = _pyplot()
    pandas = require("pandas")
    colours = _colours(frame)
    fig, axes, suites = _panels(frame, plt)
    centres = 0.5 * (ANGLE_BINS_DEG[1:] + ANGLE_BINS_DEG[:-1])
    for ax, (suite, _) in zip(axes[0], suites, strict=True):
        for method in _method_order(frame):
            runs = frame[(frame["suite"] == suite) & (frame["method"] == method)]
            bins = pandas.cut(runs["init_angle_deg"], ANGLE_BINS_DEG, include_lowest=True)
            rate = runs["success"].astype(float).groupby(bins, observed=False).mean()
            ax.plot(centres, 100 * rate.to_numpy(), "o-", ms=3, color=colours[method], label=method)
        ax.set_xlim(0, 180)
        ax.set_ylim(-3, 103)
        ax.set_xticks(ANGLE_BINS_DEG[::3])
        ax.set_xlabel("initial rotation angle (deg)")
        ax.grid(alpha=0.3)
    axes[0, 0].set_ylabel("success rate (%)")
    axes[0, -1].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0))
    return _save(fig, plt, path)


def plot_cumulative_errors(
    frame: pd.DataFrame, path: Path, *, thresholds: dict | None = None
) -> Path:
    """Share of runs with an error at most x (rotation in degrees, translation in mm).

    Runs that raised an error count in the denominator, so a curve may stay below 1.
    ``thresholds``: the run's success criteria (``max_rotation_deg``,
    ``max_translation_m``), drawn as dashed lines.
    """
    plt = _pyplot()
    colours = _colours(frame)
    fig, axes, suites = _panels(frame, plt, rows=2)
    quantities = [
        ("rotation_error_sym_deg", 1.0, "rotation error (deg)", "max_rotation_deg", 1.0),
        ("translation_error_sym_m", 1e3, "translation error (mm)", "max_translation_m", 1e3),
    ]
    for row, (column, scale, label, key, key_scale) in enumerate(quantities):
        for ax, (suite, _) in zip(axes[row], suites, strict=True):
            for method in _method_order(frame):
                runs = frame[(frame["suite"] == suite) & (frame["method"] == method)]
                values = np.sort(scale * runs[column].dropna().to_numpy(dtype=float))
                share = np.arange(1, len(values) + 1) / max(len(runs), 1)
                ax.step(
                    np.maximum(values, _FLOOR),
                    share,
                    where="post",
                    color=colours[method],
                    label=method,
                )
            if thresholds:
                ax.axvline(key_scale * thresholds[key], color="0.4", ls="--", lw=0.8)
            ax.set_xscale("log")
            ax.set_ylim(0, 1.02)
            ax.set_xlabel(label)
            ax.grid(alpha=0.3)
        axes[row, 0].set_ylabel("share of runs")
    axes[0, -1].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0))
    return _save(fig, plt, path)


def plot_times(frame: pd.DataFrame, path: Path) -> Path:
    """Box plots of the wall time per registration, per suite and method (log scale)."""
    plt = _pyplot()
    methods = _method_order(frame)
    fig, axes, suites = _panels(frame, plt, height=3.6)
    for ax, (suite, _) in zip(axes[0], suites, strict=True):
        data = [
            frame[(frame["suite"] == suite) & (frame["method"] == m)]["time_s"].to_numpy()
            for m in methods
        ]
        ax.boxplot(data, showfliers=True, flierprops={"markersize": 2})
        ax.set_xticks(range(1, len(methods) + 1), methods, rotation=45, ha="right", fontsize=7)
        ax.set_yscale("log")
        ax.grid(alpha=0.3, axis="y")
    axes[0, 0].set_ylabel("time per registration (s)")
    return _save(fig, plt, path)


def _padded(curves: list[list[float]]) -> np.ndarray:
    """Curves of unequal length as rows, each continued with its last value (a run that
    stopped keeps its final error)."""
    length = max(len(c) for c in curves)
    return np.array([c + [c[-1]] * (length - len(c)) for c in curves], dtype=float)


def plot_convergence(frame: pd.DataFrame, method: str, path: Path) -> Path:
    """Error against iteration for one spectral method (the paper's Fig. 2 and 4).

    One row per suite: translation error (mm) and rotation error (deg) of each iterate,
    thin lines for up to 40 instances (green: success, red: failure), the median over all
    instances in black and over the successful ones in dark green.
    """
    plt = _pyplot()
    runs = frame[(frame["method"] == method) & frame[CURVE_COLUMNS[0]].notna()]
    suites = _suite_order(runs)
    fig, axes = plt.subplots(len(suites), 2, figsize=(9, 2.8 * len(suites)), squeeze=False)
    panels = [
        (CURVE_COLUMNS[1], 1e3, "translation error (mm)"),
        (CURVE_COLUMNS[0], 1.0, "rotation error (deg)"),
    ]
    for row, (suite, condition) in enumerate(suites):
        here = runs[runs["suite"] == suite]
        for ax, (column, scale, label) in zip(axes[row], panels, strict=True):
            for curve, success in list(zip(here[column], here["success"], strict=True))[
                :_MAX_CURVES
            ]:
                values = np.maximum(scale * np.asarray(curve), _FLOOR)
                ax.plot(values, color="tab:green" if success else "tab:red", lw=0.6, alpha=0.5)
            wins = here[here["success"].astype(bool)]
            for subset, colour, name in (
                (here, "k", "median"),
                (wins, "darkgreen", "median of successes"),
            ):
                if len(subset):
                    median = np.median(scale * _padded(list(subset[column])), axis=0)
                    ax.plot(np.maximum(median, _FLOOR), color=colour, lw=2, label=name)
            ax.set_yscale("log")
            ax.set_xlabel("iteration")
            ax.set_ylabel(label)
            ax.set_title(f"{method}: {_suite_label(suite, condition)}", fontsize=10)
            ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=7)
    return _save(fig, plt, path)


# ---------------------------------------------------------------------------- report


def _run_config(results: Path) -> dict:
    folder = results if results.is_dir() else results.parent
    path = folder / CONFIG_FILE
    return json.loads(path.read_text()) if path.is_file() else {}


def _run_section(config: dict, frame: pd.DataFrame) -> str:
    sessions = config.get("sessions", [])
    if not sessions:
        return "Run settings unknown (no config.json next to the results).\n"
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
        f"{machine['platform']}; Python {machine['python']}, Open3D {machine['open3d']}, "
        f"NumPy {machine['numpy']}, o3d-spectral {machine['o3d_spectral']}.",
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
    }
    for table in tables:
        parts += [f"\n## {titles[table.name]}\n", f"{table.caption}\n", "\n" + to_markdown(table)]
    parts.append("\n## Plots\n")
    for title, path in figures.items():
        parts.append(f"\n**{title}**\n\n![{title}]({prefix}{path.name})\n")
    return "".join(parts)


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
    frame = load_results(results)
    config = _run_config(results)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    spectral = _spectral_methods(frame)
    summary = summary_table(frame)
    tables = [paper_table(frame), summary]
    if spectral:
        tables.append(comparison_table(summary, spectral))
    if "indistinguishable" in frame:
        tables.append(ambiguity_table(frame))
    written = [path for table in tables for path in write_table(table, out)]
    figures: dict[str, Path] = {}
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
    plots += [
        (
            f"Convergence of {m}",
            lambda p, m=m: plot_convergence(frame, m, p),
            f"convergence_{m}.png",
        )
        for m in spectral
    ]
    for title, plot, name in plots:
        figures[title] = plot(out / name)
    report = out / "report.md"
    report.write_text(_markdown_report(config, frame, tables, figures, link_prefix))
    return {path.name: path for path in [*written, *figures.values(), report]}
