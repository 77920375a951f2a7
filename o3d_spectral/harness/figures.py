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


def _colours(frame: pd.DataFrame) -> dict[str, str]:
    return {m: f"C{k % 10}" for k, m in enumerate(method_order(frame))}


#: Room around the panels, inches: left (tick labels and y label), bottom (x label), top
#: (title), between panels, and on the right for a legend outside the panels.
_MARGINS = {"left": 0.75, "bottom": 0.6, "top": 0.4, "wspace": 0.55, "hspace": 0.75}
_LEGEND_ROOM = 2.0


def _figure(plt, rows: int, columns: int, panel: tuple[float, float], **room: float):
    """A figure of ``rows x columns`` panels of ``panel`` (width, height) inches, with the
    margins of :data:`_MARGINS` (overridden by ``room``, plus ``right``) fixed in inches.

    Fixed margins instead of ``tight_layout`` or ``bbox_inches="tight"``: each of those
    draws the figure once more to measure it, which doubled the time of every plot.
    """
    margin = _MARGINS | {"right": 0.25} | room
    width = margin["left"] + margin["right"] + columns * panel[0]
    width += (columns - 1) * margin["wspace"]
    height = margin["bottom"] + margin["top"] + rows * panel[1] + (rows - 1) * margin["hspace"]
    fig, axes = plt.subplots(rows, columns, figsize=(width, height), squeeze=False)
    fig.subplots_adjust(
        left=margin["left"] / width,
        right=1 - margin["right"] / width,
        bottom=margin["bottom"] / height,
        top=1 - margin["top"] / height,
        wspace=margin["wspace"] / panel[0],
        hspace=margin["hspace"] / panel[1],
    )
    return fig, axes


def _panels(frame: pd.DataFrame, plt, *, rows: int = 1, height: float = 2.6, **room: float):
    suites = suite_order(frame)
    fig, axes = _figure(plt, rows, len(suites), (2.9, height), **room)
    for ax, (suite, condition) in zip(axes[0], suites, strict=True):
        ax.set_title(suite_label(suite, condition), fontsize=10)
    return fig, axes, suites


def _save(fig, plt, path: Path) -> Path:
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_success_vs_angle(frame: pd.DataFrame, path: Path) -> Path:
    """Success rate (%) per bin of the initial rotation angle (0-180 degrees, 20-degree bins)."""
    plt = _pyplot()
    cells, empty = by_suite_and_method(frame), frame.iloc[:0]
    pandas = require("pandas")
    colours = _colours(frame)
    fig, axes, suites = _panels(frame, plt, right=_LEGEND_ROOM)
    centres = 0.5 * (ANGLE_BINS_DEG[1:] + ANGLE_BINS_DEG[:-1])
    for ax, (suite, _) in zip(axes[0], suites, strict=True):
        for method in method_order(frame):
            runs = cells.get((suite, method), empty)
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
    cells, empty = by_suite_and_method(frame), frame.iloc[:0]
    colours = _colours(frame)
    fig, axes, suites = _panels(frame, plt, rows=2, right=_LEGEND_ROOM)
    quantities = [
        ("rotation_error_sym_deg", 1.0, "rotation error (deg)", "max_rotation_deg", 1.0),
        ("translation_error_sym_m", 1e3, "translation error (mm)", "max_translation_m", 1e3),
    ]
    for row, (column, scale, label, key, key_scale) in enumerate(quantities):
        for ax, (suite, _) in zip(axes[row], suites, strict=True):
            for method in method_order(frame):
                runs = cells.get((suite, method), empty)
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
            _log_axis(ax, "x")
            ax.set_ylim(0, 1.02)
            ax.set_xlabel(label)
            ax.grid(alpha=0.3)
        axes[row, 0].set_ylabel("share of runs")
    axes[0, -1].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0))
    return _save(fig, plt, path)


def plot_times(frame: pd.DataFrame, path: Path) -> Path:
    """Box plots of the wall time per registration, per suite and method (log scale)."""
    plt = _pyplot()
    cells, empty = by_suite_and_method(frame), frame.iloc[:0]
    methods = method_order(frame)
    fig, axes, suites = _panels(frame, plt, bottom=1.25)
    for ax, (suite, _) in zip(axes[0], suites, strict=True):
        data = [
            cells.get((suite, m), empty)["time_s"].to_numpy()
            for m in methods
        ]
        ax.boxplot(data, showfliers=True, flierprops={"markersize": 2})
        ax.set_xticks(range(1, len(methods) + 1), methods, rotation=45, ha="right", fontsize=7)
        _log_axis(ax)
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
    LineCollection = require("matplotlib.collections").LineCollection
    runs = frame[(frame["method"] == method) & frame[CURVE_COLUMNS[0]].notna()]
    suites = suite_order(runs)
    fig, axes = _figure(plt, len(suites), 2, (3.6, 2.1), wspace=0.8)
    panels = [
        (CURVE_COLUMNS[1], 1e3, "translation error (mm)"),
        (CURVE_COLUMNS[0], 1.0, "rotation error (deg)"),
    ]
    for row, (suite, condition) in enumerate(suites):
        here = runs[runs["suite"] == suite]
        for ax, (column, scale, label) in zip(axes[row], panels, strict=True):
            shown = here.iloc[:_MAX_CURVES]
            # One collection per panel, not a line per instance: far fewer artists to draw.
            lines = [
                np.column_stack([np.arange(len(c)), np.maximum(scale * np.asarray(c), _FLOOR)])
                for c in shown[column]
            ]
            colours = ["tab:green" if s else "tab:red" for s in shown["success"]]
            ax.add_collection(LineCollection(lines, colors=colours, lw=0.6, alpha=0.5))
            ax.autoscale_view()
            wins = here[here["success"].astype(bool)]
            for subset, colour, name in (
                (here, "k", "median"),
                (wins, "darkgreen", "median of successes"),
            ):
                if len(subset):
                    median = np.median(scale * _padded(list(subset[column])), axis=0)
                    ax.plot(np.maximum(median, _FLOOR), color=colour, lw=2, label=name)
            _log_axis(ax)
            ax.set_xlabel("iteration")
            ax.set_ylabel(label)
            ax.set_title(f"{method}: {suite_label(suite, condition)}", fontsize=10)
            ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=7)
    return _save(fig, plt, path)
