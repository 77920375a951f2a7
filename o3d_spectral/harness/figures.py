"""Plots of an evaluation run (PNG, matplotlib on the Agg backend).

Success rate against the initial rotation angle, cumulative error curves, time per
method, and for each spectral method its convergence curves (error against iteration,
the paper's Fig. 2 and 4). All errors are the symmetry-aware ones; translation errors are
measured at the object's centroid (:mod:`o3d_spectral.harness.metrics`).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from o3d_spectral.harness._optional import require
from o3d_spectral.harness.records import CURVE_COLUMNS
from o3d_spectral.harness.tables import (
    by_suite_and_method,
    method_order,
    suite_label,
    suite_order,
)

if TYPE_CHECKING:
    import pandas as pd

__all__ = [
    "ANGLE_BINS_DEG",
    "plot_convergence",
    "plot_cumulative_errors",
    "plot_success_vs_angle",
    "plot_times",
]

ANGLE_BINS_DEG = np.arange(0.0, 181.0, 20.0)
_MAX_CURVES = 40  # instance curves drawn per panel (the median uses all)
_FLOOR = 1e-3  # smallest error drawn on log axes (deg, mm)


def _pyplot():
    matplotlib = require("matplotlib")
    matplotlib.use("Agg")
    return require("matplotlib.pyplot")


def _log_axis(ax, which: str = "y") -> None:
    """A log scale with ticks at the decades only: the minor ticks of a log axis (eight a
    decade, each with its label and grid line) took most of a report's time."""
    if which == "y":
        ax.set_yscale("log")
        ax.yaxis.set_minor_locator(require("matplotlib.ticker").NullLocator())
    else:
        ax.set_xscale("log")
        ax.xaxis.set_minor_locator(require("matplotlib.ticker").NullLocator())


def _styles(frame: pd.DataFrame) -> dict[str, dict[str, str]]:
    """Colour and line style of each method: the ten colours of the default cycle solid,
    then again dashed, then dotted, so that more than ten methods stay told apart."""
    return {
        m: {"color": f"C{k % 10}", "ls": ("-", "--", ":")[k // 10 % 3]}
        for k, m in enumerate(method_order(frame))
    }


#: Room around the panels, inches: left (tick labels and y label), bottom (x label), top
#: (title), between panels, and on the right for a legend outside the panels.
_MARGINS = {"left": 0.75, "bottom": 0.6, "top": 0.4, "wspace": 0.55, "hspace": 0.75}
_LEGEND_ROOM = 2.0


def _figure(
    plt,
    rows: int,
    columns: int,
    panel: tuple[float, float],
    share: dict[str, bool | str] | None = None,
    **room: float,
):
    """A figure of ``rows x columns`` panels of ``panel`` (width, height) inches, with the
    margins of :data:`_MARGINS` (overridden by ``room``, plus ``right``) fixed in inches.

    Fixed margins instead of ``tight_layout`` or ``bbox_inches="tight"``: each of those
    draws the figure once more to measure it, which doubled the time of every plot.
    ``share``: ``sharex`` and ``sharey`` of ``plt.subplots``; a shared axis labels its
    ticks on the outer panels only (fewer texts, the costliest part of drawing a panel).
    """
    margin = _MARGINS | {"right": 0.25} | room
    width = margin["left"] + margin["right"] + columns * panel[0]
    width += (columns - 1) * margin["wspace"]
    height = margin["bottom"] + margin["top"] + rows * panel[1] + (rows - 1) * margin["hspace"]
    fig, axes = plt.subplots(rows, columns, figsize=(width, height), squeeze=False, **(share or {}))
    fig.subplots_adjust(
        left=margin["left"] / width,
        right=1 - margin["right"] / width,
        bottom=margin["bottom"] / height,
        top=1 - margin["top"] / height,
        wspace=margin["wspace"] / panel[0],
        hspace=margin["hspace"] / panel[1],
    )
    return fig, axes


def _title(ax, text: str) -> None:
    """Title a panel at a fixed height: without ``y``, matplotlib measures the panel's
    tick labels at every draw to lift the title over any above the axes (there are none)."""
    ax.set_title(text, fontsize=10, y=1.0)


def _panels(
    frame: pd.DataFrame,
    plt,
    *,
    rows: int = 1,
    height: float = 2.6,
    share: dict[str, bool | str] | None = None,
    **room: float,
):
    suites = suite_order(frame)
    fig, axes = _figure(plt, rows, len(suites), (2.9, height), share, **room)
    for ax, (suite, condition) in zip(axes[0], suites, strict=True):
        _title(ax, suite_label(suite, condition))
    return fig, axes, suites


def _save(fig, plt, path: Path) -> Path:
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _success_by_angle(runs: pd.DataFrame) -> np.ndarray:
    """Share of successes per bin of :data:`ANGLE_BINS_DEG` (NaN where a bin is empty):
    bins closed on the right, the first also on the left, as ``pandas.cut`` with
    ``include_lowest``; runs whose success is unknown are left out."""
    angles = runs["init_angle_deg"].to_numpy(dtype=float)
    success = runs["success"].to_numpy(dtype=float)
    counted = (angles >= ANGLE_BINS_DEG[0]) & (angles <= ANGLE_BINS_DEG[-1])
    counted &= ~np.isnan(success)
    bins = np.maximum(np.searchsorted(ANGLE_BINS_DEG, angles[counted]), 1) - 1
    size = len(ANGLE_BINS_DEG) - 1
    runs_in = np.bincount(bins, minlength=size)
    wins_in = np.bincount(bins, weights=success[counted], minlength=size)
    with np.errstate(invalid="ignore"):
        return wins_in / runs_in


def plot_success_vs_angle(frame: pd.DataFrame, path: Path) -> Path:
    """Success rate (%) per bin of the initial rotation angle (0-180 degrees, 20-degree bins)."""
    plt = _pyplot()
    cells, empty = by_suite_and_method(frame), frame.iloc[:0]
    styles = _styles(frame)
    share = {"sharey": True}
    fig, axes, suites = _panels(frame, plt, share=share, right=_LEGEND_ROOM)
    centres = 0.5 * (ANGLE_BINS_DEG[1:] + ANGLE_BINS_DEG[:-1])
    for ax, (suite, _) in zip(axes[0], suites, strict=True):
        for method, style in styles.items():
            rate = _success_by_angle(cells.get((suite, method), empty))
            ax.plot(centres, 100 * rate, marker="o", ms=3, label=method, **style)
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
    cells, empty = by_suite_and_method(frame), frame.iloc[:0]
    styles = _styles(frame)
    share = {"sharey": True}
    fig, axes, suites = _panels(frame, plt, rows=2, share=share, right=_LEGEND_ROOM)
    quantities = [
        ("rotation_error_sym_deg", 1.0, "rotation error (deg)", "max_rotation_deg"),
        ("translation_error_sym_m", 1e3, "translation error (mm)", "max_translation_m"),
    ]
    for row, (column, scale, label, key) in enumerate(quantities):
        for ax, (suite, _) in zip(axes[row], suites, strict=True):
            for method, style in styles.items():
                runs = cells.get((suite, method), empty)
                values = np.sort(scale * runs[column].dropna().to_numpy(dtype=float))
                share_of_runs = np.arange(1, len(values) + 1) / max(len(runs), 1)
                x = np.maximum(values, _FLOOR)
                ax.step(x, share_of_runs, where="post", label=method, **style)
            if thresholds:
                ax.axvline(scale * thresholds[key], color="0.4", ls="--", lw=0.8)
            _log_axis(ax, "x")
            ax.set_ylim(0, 1.02)
            ax.set_xlabel(label)
            ax.grid(alpha=0.3)
        axes[row, 0].set_ylabel("share of runs")
    axes[0, -1].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0))
    return _save(fig, plt, path)


def _draw_boxes(ax, data: list[np.ndarray]) -> None:
    """Horizontal box plots of ``data`` at y = 1, 2, ... (quartiles, whiskers at 1.5 IQR,
    outliers as circles, as ``ax.boxplot``), drawn as three artists in all instead of
    seven per box."""
    cbook = require("matplotlib.cbook")
    LineCollection = require("matplotlib.collections").LineCollection
    outlines, medians, fliers = [], [], []
    for y, stats in enumerate(cbook.boxplot_stats(data), 1):
        low, high, q1, q3 = y - 0.25, y + 0.25, stats["q1"], stats["q3"]
        outlines.append([(q1, low), (q3, low), (q3, high), (q1, high), (q1, low)])
        for end, edge in ((stats["whislo"], q1), (stats["whishi"], q3)):
            outlines += [[(end, y), (edge, y)], [(end, y - 0.125), (end, y + 0.125)]]
        medians.append([(stats["med"], low), (stats["med"], high)])
        fliers += [(value, y) for value in stats["fliers"]]
    ax.add_collection(LineCollection(outlines, colors="k", lw=1))
    ax.add_collection(LineCollection(medians, colors="C1", lw=1))
    x, y = np.array(fliers, dtype=float).reshape(-1, 2).T
    ax.plot(x, y, "o", ms=2, mfc="none", mec="k")
    ax.autoscale_view()


def plot_times(frame: pd.DataFrame, path: Path) -> Path:
    """Box plots of the wall time per registration, per suite and method (log scale)."""
    plt = _pyplot()
    cells, empty = by_suite_and_method(frame), frame.iloc[:0]
    methods = method_order(frame)
    share = {"sharey": True}
    fig, axes, suites = _panels(frame, plt, share=share, left=1.9)
    for ax, (suite, _) in zip(axes[0], suites, strict=True):
        _draw_boxes(ax, [cells.get((suite, m), empty)["time_s"].to_numpy() for m in methods])
        _log_axis(ax, "x")
        ax.set_xlabel("time per registration (s)")
        ax.grid(alpha=0.3, axis="x")
    axes[0, 0].set_yticks(range(1, len(methods) + 1), methods, fontsize=7)
    axes[0, 0].set_ylim(len(methods) + 0.5, 0.5)  # the first method on top
    return _save(fig, plt, path)


def _padded(curves: list[list[float]]) -> np.ndarray:
    """Curves of unequal length as rows, each continued with its last value (a run that
    stopped keeps its final error)."""
    length = max(len(c) for c in curves)
    return np.array([c + [c[-1]] * (length - len(c)) for c in curves], dtype=float)


#: The convergence figure's columns: curve, scale to the unit shown, axis label.
_CONVERGENCE_PANELS = (
    (CURVE_COLUMNS[1], 1e3, "translation error (mm)"),
    (CURVE_COLUMNS[0], 1.0, "rotation error (deg)"),
)


def _convergence_figure(plt, rows: int):
    """Empty convergence panels: a row per suite, translation and rotation error (log
    scale) against iteration."""
    share = {"sharex": "col"}
    fig, axes = _figure(plt, rows, 2, (3.6, 2.1), share, wspace=0.8, hspace=0.45)
    for ax, (_, _, label) in zip(axes.flat, _CONVERGENCE_PANELS * rows, strict=True):
        _log_axis(ax)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("iteration")
    return fig, axes


def _draw_curves(ax, runs: pd.DataFrame, column: str, scale: float) -> None:
    """Replace the curves of a convergence panel by those of ``runs``: thin lines for the
    first :data:`_MAX_CURVES` (green: success, red: failure), the median over all runs in
    black and over the successful ones in dark green."""
    LineCollection = require("matplotlib.collections").LineCollection
    for artist in [*ax.lines, *ax.collections]:
        artist.remove()
    ax.relim()  # forget the extent of the removed curves
    shown = runs.iloc[:_MAX_CURVES]
    # One collection per panel, not a line per instance: far fewer artists to draw.
    lines = [
        np.column_stack([np.arange(len(c)), np.maximum(scale * np.asarray(c), _FLOOR)])
        for c in shown[column]
    ]
    colours = ["tab:green" if s else "tab:red" for s in shown["success"]]
    ax.add_collection(LineCollection(lines, colors=colours, lw=0.6, alpha=0.5))
    wins = runs[runs["success"].astype(bool)]
    for subset, colour, name in ((runs, "k", "median"), (wins, "darkgreen", "median of successes")):
        if len(subset):
            median = np.median(scale * _padded(list(subset[column])), axis=0)
            ax.plot(np.maximum(median, _FLOOR), color=colour, lw=2, label=name)


def plot_convergence(frame: pd.DataFrame, paths: dict[str, Path]) -> dict[str, Path]:
    """Error against iteration, a figure per spectral method (the paper's Fig. 2 and 4).

    One row per suite: translation error (mm) and rotation error (deg) of each iterate,
    thin lines for up to 40 instances (green: success, red: failure), the median over all
    instances in black and over the successful ones in dark green.

    Parameters
    ----------
    frame : pandas.DataFrame
        The run's rows (:func:`~o3d_spectral.harness.records.load_results`).
    paths : dict of str to Path
        Where to write the figure of each method.

    Returns
    -------
    dict of str to Path
        ``paths``, once written.

    Notes
    -----
    The methods' figures are drawn in turn into one matplotlib figure, its curves replaced
    each time: its panels, ticks and text layouts are made once, not once per method.
    """
    plt = _pyplot()
    fig = axes = None
    for method, path in paths.items():
        runs = frame[(frame["method"] == method) & frame[CURVE_COLUMNS[0]].notna()]
        suites = suite_order(runs)
        if axes is None or len(axes) != len(suites):
            if fig is not None:
                plt.close(fig)
            fig, axes = _convergence_figure(plt, len(suites))
        for row, (suite, condition) in enumerate(suites):
            here = runs[runs["suite"] == suite]
            for ax, (column, scale, _) in zip(axes[row], _CONVERGENCE_PANELS, strict=True):
                _draw_curves(ax, here, column, scale)
                _title(ax, f"{method}: {suite_label(suite, condition)}")
        for ax in axes.flat:
            ax.autoscale_view()
        axes[0, 0].legend(fontsize=7)
        fig.savefig(path, dpi=110)
    if fig is not None:
        plt.close(fig)
    return dict(paths)
