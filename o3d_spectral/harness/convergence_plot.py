"""Convergence plots of an evaluation run: for each spectral method, error against iteration
per suite (the paper's Fig. 2 and 4), one PNG per method.

The methods' figures share one layout, axis limits that hold every method's curves (so
they are on one scale), and so their ticks: they are drawn as one matplotlib figure whose
frame (axes, ticks, labels, grid, suite titles) is drawn once and kept as an image, each
method's curves, name and legend drawn over a copy of it (blitting): about a quarter of the
time of drawing each figure whole.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from o3d_spectral.harness._optional import require
from o3d_spectral.harness._plotting import (
    FLOOR,
    draw,
    figure,
    log_axis,
    pyplot,
    title,
    write_png,
)
from o3d_spectral.harness.records import CURVE_COLUMNS
from o3d_spectral.harness.tables import suite_label, suite_order

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["plot_convergence"]

_MAX_CURVES = 40  # instance curves drawn per panel (the median uses all)
#: The columns of panels: curve, scale to the unit shown, axis label.
_COLUMNS = (
    (CURVE_COLUMNS[1], 1e3, "translation error (mm)"),
    (CURVE_COLUMNS[0], 1.0, "rotation error (deg)"),
)


@dataclass(frozen=True)
class _Panel:
    """The curves of one panel: thin lines of (iteration, error) points and their colours,
    and the medians as (error by iteration, colour, label)."""

    lines: list[np.ndarray]
    colours: list[str]
    medians: list[tuple[np.ndarray, str, str]]

    def corners(self) -> list[tuple[float, float]]:
        """Two points spanning every curve of the panel."""
        errors = [line[:, 1] for line in self.lines] + [m for m, _, _ in self.medians]
        last = max(len(e) for e in errors) - 1
        low, high = min(e.min() for e in errors), max(e.max() for e in errors)
        return [(0.0, float(low)), (float(last), float(high))]


def _lines(curves: list[list[float]], scale: float) -> list[np.ndarray]:
    """Each curve as its (iteration, error) points, the errors scaled and at least
    :data:`FLOOR`: made as one array and split (two small arrays a curve took longer)."""
    lengths = np.array([len(c) for c in curves])
    ends = np.cumsum(lengths)
    errors = np.fromiter(itertools.chain.from_iterable(curves), float, ends[-1])
    iterations = np.arange(ends[-1]) - np.repeat(ends - lengths, lengths)
    points = np.column_stack([iterations, np.maximum(scale * errors, FLOOR)])
    return np.split(points, ends[:-1])


def padded_curves(curves: list[list[float]]) -> np.ndarray:
    """Curves of unequal length as rows, each continued with its last value (a run that
    stopped keeps its final error)."""
    lengths = np.array([len(c) for c in curves])
    values = np.fromiter(itertools.chain.from_iterable(curves), float, lengths.sum())
    starts = np.cumsum(lengths) - lengths
    steps = np.minimum(np.arange(lengths.max()), lengths[:, None] - 1)
    return values[starts[:, None] + steps]


def median_curves(curves: list[list[float]], success: np.ndarray, scale: float) -> list[tuple]:
    """The median by iteration over all ``curves`` (black) and over the successful runs'
    (dark green), each as long as the longest of its curves, as (errors, colour, label)."""
    padded = scale * padded_curves(curves)
    longest_win = max((len(c) for c, won in zip(curves, success, strict=True) if won), default=0)
    subsets = [(padded, "k", "median")]
    subsets += [(padded[success, :longest_win], "darkgreen", "median of successes")]
    return [
        (np.maximum(np.median(errors, axis=0), FLOOR), colour, name)
        for errors, colour, name in subsets
        if len(errors)
    ]


def _panel(runs: pd.DataFrame, column: str, scale: float) -> _Panel:
    """Thin lines for the first :data:`_MAX_CURVES` runs (green: success, red: failure),
    the median over all runs in black and over the successful ones in dark green."""
    curves = list(runs[column])
    success = runs["success"].astype(bool).to_numpy()
    shown = curves[:_MAX_CURVES]
    colours = ["tab:green" if won else "tab:red" for won in success[: len(shown)]]
    return _Panel(_lines(shown, scale), colours, median_curves(curves, success, scale))


def _method_panels(runs: pd.DataFrame, suites: list[tuple[str, str]]) -> list[_Panel]:
    """One method's panels, row by row: a row per suite, translation then rotation."""
    by_suite = dict(tuple(runs.groupby("suite", sort=False)))
    return [
        _panel(by_suite[suite], column, scale)
        for suite, _ in suites
        for column, scale, _ in _COLUMNS
    ]


def _frame(plt, suites: list[tuple[str, str]], panels: list[list[_Panel]]):
    """The figure, its axes with limits that hold the curves of every method's ``panels``,
    titled by suite, and its frame drawn without curves (an image to draw them over)."""
    rows = len(suites)
    share = {"sharex": "col"}
    fig, axes = figure(plt, rows, 2, (3.6, 2.1), share, top=0.7, wspace=0.8, hspace=0.45)
    for k, (ax, (_, _, label)) in enumerate(zip(axes.flat, _COLUMNS * rows, strict=True)):
        log_axis(ax)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        title(ax, suite_label(*suites[k // len(_COLUMNS)]))
        ax.update_datalim([point for method in panels for point in method[k].corners()])
    for ax in axes.flat:
        ax.autoscale_view()
        ax.set_autoscale_on(False)  # the curves drawn later leave the limits alone
    for ax in axes[-1]:
        ax.set_xlabel("iteration")
    draw(fig)
    return fig, axes, fig.canvas.copy_from_bbox(fig.bbox)


def _draw(fig, axes, background, panels: list[_Panel], method: str, path: Path) -> None:
    """Draw the ``panels`` of ``method`` and its name, as the figure's title, over the frame
    ``background`` and write the image to ``path``.

    The method is named once, not in each panel's title: a text is laid out anew for
    every new string, and eight titles a method took a third of the time of its curves.
    """
    LineCollection = require("matplotlib.collections").LineCollection
    fig.canvas.restore_region(background)
    drawn = []
    for ax, panel in zip(axes.flat, panels, strict=True):
        # One collection per panel, not a line per instance: far fewer artists to draw.
        lines = LineCollection(panel.lines, colors=panel.colours, lw=0.6, alpha=0.5)
        drawn += [(ax, ax.add_collection(lines, autolim=False))]
        for errors, colour, name in panel.medians:
            drawn += [(ax, line) for line in ax.plot(errors, color=colour, lw=2, label=name)]
    drawn.append((axes[0, 0], axes[0, 0].legend(fontsize=7)))
    for ax, artist in drawn:
        ax.draw_artist(artist)
    fig.draw_artist(fig.suptitle(method, fontsize=12, y=1 - 0.2 / fig.get_figheight()))
    write_png(fig, path)
    for _, artist in drawn:
        artist.remove()


def plot_convergence(frame: pd.DataFrame, paths: dict[str, Path]) -> dict[str, Path]:
    """Error against iteration, a figure per spectral method (the paper's Fig. 2 and 4).

    One row per suite: translation error (mm) and rotation error (deg) of each iterate,
    thin lines for up to 40 instances (green: success, red: failure), the median over all
    instances in black and over the successful ones in dark green. Methods run on the same
    suites share the axis limits.

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
    """
    if not paths:  # a run without spectral methods has no curve columns
        return {}
    plt = pyplot()
    groups: dict[tuple, dict[str, list[_Panel]]] = {}  # methods by the suites they ran
    columns = ["method", "suite", "condition", "success", *CURVE_COLUMNS]
    with_curves = frame.loc[frame[CURVE_COLUMNS[0]].notna(), columns]
    for method in paths:
        runs = with_curves[with_curves["method"] == method]
        suites = suite_order(runs)
        groups.setdefault(tuple(suites), {})[method] = _method_panels(runs, suites)
    for suites, methods in groups.items():
        fig, axes, background = _frame(plt, list(suites), list(methods.values()))
        for method, panels in methods.items():
            _draw(fig, axes, background, panels, method, paths[method])
        plt.close(fig)
    return dict(paths)
