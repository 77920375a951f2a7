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
from o3d_spectral.harness.tables import method_order, suite_label, suite_order

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


def _colours(frame: pd.DataFrame) -> dict[str, str]:
    return {m: f"C{k % 10}" for k, m in enumerate(method_order(frame))}


def _panels(frame: pd.DataFrame, plt, *, rows: int = 1, height: float = 3.2):
    suites = suite_order(frame)
    fig, axes = plt.subplots(
        rows, len(suites), figsize=(3.6 * len(suites), height * rows), squeeze=False
    )
    for ax, (suite, condition) in zip(axes[0], suites, strict=True):
        ax.set_title(suite_label(suite, condition), fontsize=10)
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
        for method in method_order(frame):
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
            for method in method_order(frame):
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
    methods = method_order(frame)
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
    suites = suite_order(runs)
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
            ax.set_title(f"{method}: {suite_label(suite, condition)}", fontsize=10)
            ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=7)
    return _save(fig, plt, path)
