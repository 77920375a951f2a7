"""Plots of an evaluation run (PNG, matplotlib on the Agg backend).

Success rate against the initial rotation angle, cumulative error curves, time per
method, and for each spectral method its convergence curves (error against iteration,
the paper's Fig. 2 and 4, drawn by :mod:`~o3d_spectral.harness.convergence_plot`). All
errors are the symmetry-aware ones; translation errors are measured at the object's
centroid (:mod:`o3d_spectral.harness.metrics`).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from o3d_spectral.harness._optional import require
from o3d_spectral.harness._plotting import (
    FLOOR,
    LEGEND_ROOM,
    figure,
    log_axis,
    pyplot,
    save,
    title,
)
from o3d_spectral.harness.constants import ANGLE_BINS_DEG
from o3d_spectral.harness.convergence_plot import plot_convergence
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


def _styles(frame: pd.DataFrame) -> dict[str, dict[str, str]]:
    """Colour and line style of each method: the ten colours of the default cycle solid,
    then again dashed, then dotted, so that more than ten methods stay told apart."""
    return {
        m: {"color": f"C{k % 10}", "ls": ("-", "--", ":")[k // 10 % 3]}
        for k, m in enumerate(method_order(frame))
    }


def _panels(
    frame: pd.DataFrame,
    plt,
    *,
    rows: int = 1,
    height: float = 2.6,
    share: dict[str, bool | str] | None = None,
    **room: float,
):
    """A figure of a column of panels per suite (``rows`` of them), titled by suite in
    the first row; the figure, its axes and the (suite, condition) pairs."""
    suites = suite_order(frame)
    fig, axes = figure(plt, rows, len(suites), (2.9, height), share, **room)
    for ax, (suite, condition) in zip(axes[0], suites, strict=True):
        title(ax, suite_label(suite, condition))
    return fig, axes, suites


def success_by_angle(runs: pd.DataFrame) -> np.ndarray:
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
    plt = pyplot()
    cells = by_suite_and_method(frame, ["init_angle_deg", "success"])
    empty = frame.iloc[:0]
    styles = _styles(frame)
    share = {"sharey": True}
    fig, axes, suites = _panels(frame, plt, share=share, right=LEGEND_ROOM)
    centres = 0.5 * (ANGLE_BINS_DEG[1:] + ANGLE_BINS_DEG[:-1])
    for ax, (suite, _) in zip(axes[0], suites, strict=True):
        for method, style in styles.items():
            rate = success_by_angle(cells.get((suite, method), empty))
            ax.plot(centres, 100 * rate, marker="o", ms=3, label=method, **style)
        ax.set_xlim(0, 180)
        ax.set_ylim(-3, 103)
        ax.set_xticks(ANGLE_BINS_DEG[::3])
        ax.set_xlabel("initial rotation angle (deg)")
        ax.grid(alpha=0.3)
    axes[0, 0].set_ylabel("success rate (%)")
    axes[0, -1].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0))
    return save(fig, plt, path)


def plot_cumulative_errors(
    frame: pd.DataFrame, path: Path, *, thresholds: dict | None = None
) -> Path:
    """Share of runs with an error at most x (rotation in degrees, translation in mm).

    Runs that raised an error count in the denominator, so a curve may stay below 1.
    ``thresholds``: the run's success criteria (``max_rotation_deg``,
    ``max_translation_m``), drawn as dashed lines.
    """
    plt = pyplot()
    quantities = [
        ("rotation_error_sym_deg", 1.0, "rotation error (deg)", "max_rotation_deg"),
        ("translation_error_sym_m", 1e3, "translation error (mm)", "max_translation_m"),
    ]
    cells = by_suite_and_method(frame, [column for column, *_ in quantities])
    empty = frame.iloc[:0]
    styles = _styles(frame)
    share = {"sharey": True}
    fig, axes, suites = _panels(frame, plt, rows=2, share=share, right=LEGEND_ROOM)
    for row, (column, scale, label, key) in enumerate(quantities):
        for ax, (suite, _) in zip(axes[row], suites, strict=True):
            for method, style in styles.items():
                runs = cells.get((suite, method), empty)
                values = np.sort(scale * runs[column].dropna().to_numpy(dtype=float))
                share_of_runs = np.arange(1, len(values) + 1) / max(len(runs), 1)
                x = np.maximum(values, FLOOR)
                ax.step(x, share_of_runs, where="post", label=method, **style)
            if thresholds:
                ax.axvline(scale * thresholds[key], color="0.4", ls="--", lw=0.8)
            log_axis(ax, "x")
            ax.set_ylim(0, 1.02)
            ax.set_xlabel(label)
            ax.grid(alpha=0.3)
        axes[row, 0].set_ylabel("share of runs")
    axes[0, -1].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0))
    return save(fig, plt, path)


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
    plt = pyplot()
    cells, empty = by_suite_and_method(frame, ["time_s"]), frame.iloc[:0]
    methods = method_order(frame)
    fig, axes, suites = _panels(frame, plt, left=1.9)
    for ax, (suite, _) in zip(axes[0], suites, strict=True):
        _draw_boxes(ax, [cells.get((suite, m), empty)["time_s"].to_numpy() for m in methods])
        log_axis(ax, "x")
        ax.set_xlabel("time per registration (s)")
        ax.grid(alpha=0.3, axis="x")
        ax.set_ylim(len(methods) + 0.5, 0.5)  # the first method on top
        # Method names on the first panel only; no y ticks at all on the others.
        ax.yaxis.set_major_locator(require("matplotlib.ticker").NullLocator())
    axes[0, 0].set_yticks(range(1, len(methods) + 1), methods, fontsize=7)
    return save(fig, plt, path)
