"""Result tables of an evaluation run, as numbers (:class:`Table`); written out by
:mod:`o3d_spectral.harness.writers` (Markdown, LaTeX, CSV).

* ``table1``: the paper's Table 1, mean squared translation (m^2) and rotation (rad^2)
  errors per method, columns C-1 (full), C-2 (partial), C-3 (cluttered), then the other
  suites;
* ``summary``: per suite and method, success rate, median errors over the successes,
  median and 90th-percentile time;
* ``comparison``: each spectral method against the most successful other method, suite
  by suite, with a plain verdict (where spectral loses);
* ``ambiguity``: per suite, the instances whose view leaves a wrong pose open;
* ``bop``: on a BOP dataset's instances, BOP's average recalls (AR, VSD, MSSD, MSPD);
* ``pairs``: on 3DMatch-layout scan pairs, registration recall, RE and TE.

Also the order and labels of methods and suites that the plots share.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from o3d_spectral.harness._optional import require
from o3d_spectral.harness.records import CURVE_COLUMNS

if TYPE_CHECKING:
    import pandas as pd

__all__ = [
    "PAPER_CONDITIONS",
    "Table",
    "ambiguity_table",
    "bop_table",
    "by_suite_and_method",
    "comparison_table",
    "method_order",
    "pairs_table",
    "paper_table",
    "spectral_methods",
    "suite_label",
    "suite_order",
    "summary_table",
]

#: Columns of the paper's Table 1.
PAPER_CONDITIONS = {"full": "C-1", "partial": "C-2", "cluttered": "C-3"}


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


def method_order(frame: pd.DataFrame) -> list[str]:
    """The methods of ``frame``: in the order the run named them (``frame.attrs["methods"]``,
    set by :func:`~o3d_spectral.harness.records.load_results`), else the registry's, then
    any others by name."""
    present = list(frame["method"].unique())  # in order of appearance
    order = frame.attrs.get("methods")
    if not order:  # the registry imports Open3D: only when the run does not say
        from o3d_spectral.harness.methods import method_names

        order = method_names()
    known = [m for m in order if m in present]
    return known + sorted(m for m in present if m not in known)


def suite_order(frame: pd.DataFrame) -> list[tuple[str, str]]:
    """(suite, condition) pairs: C-1, C-2, C-3 first, then the others by name."""
    # A set of the column pairs: a third of the time of DataFrame.drop_duplicates.
    pairs = set(zip(frame["suite"].to_numpy(), frame["condition"].to_numpy(), strict=True))
    rank = {condition: k for k, condition in enumerate(PAPER_CONDITIONS)}
    return sorted(pairs, key=lambda p: (rank.get(p[1], len(rank)), p[0]))


def suite_label(suite: str, condition: str) -> str:
    return f"{PAPER_CONDITIONS[condition]} ({suite})" if condition in PAPER_CONDITIONS else suite


def by_suite_and_method(
    frame: pd.DataFrame, columns: list[str]
) -> dict[tuple[str, str], pd.DataFrame]:
    """The runs of each (suite, method) pair present, split once (a boolean mask per pair
    scanned every row again for each table cell and plot line), with only the ``columns``
    the caller reads (splitting every column of the rows took three times as long)."""
    groups = frame.groupby(["suite", "method"], sort=False)[columns]
    return {key: runs for key, runs in groups}


def spectral_methods(frame: pd.DataFrame) -> list[str]:
    """Methods that reported convergence curves (iterative spectral variants)."""
    if CURVE_COLUMNS[0] not in frame:
        return []
    pairs = zip(frame["method"].to_numpy(), frame[CURVE_COLUMNS[0]].to_numpy(), strict=True)
    with_curves = {m for m, curve in pairs if isinstance(curve, list) and len(curve) > 0}
    return [m for m in method_order(frame) if m in with_curves]


# ---------------------------------------------------------------------------- tables


def paper_table(frame: pd.DataFrame) -> Table:
    """The paper's Table 1: mean squared symmetry-aware errors per method and suite."""
    pandas = require("pandas")
    suites = suite_order(frame)
    errors = {
        "squared_translation_error_m2": "translation (m²)",
        "squared_rotation_error_rad2": "rotation (rad²)",
    }
    cells = by_suite_and_method(frame, list(errors))
    empty = frame.iloc[:0]
    rows = []
    for method in method_order(frame):
        for column, label in errors.items():
            row = {"method": method, "error": label}
            for suite, condition in suites:
                cell = cells.get((suite, method), empty)
                row[suite_label(suite, condition)] = cell[column].mean()
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
    # What each run counts as, found once for every row rather than cell by cell.
    counted = frame.assign(
        success=frame["success"].astype(bool),
        raised=frame["error"].notna() if "error" in frame else False,
        open_view=_flagged(frame),
    )
    cells = by_suite_and_method(
        counted,
        ["success", "rotation_error_sym_deg", "translation_error_sym_m", "time_s", "raised",
         "open_view"],
    )
    rows, methods = [], method_order(frame)
    for suite, condition in suite_order(frame):
        for method in methods:
            runs = cells.get((suite, method))
            if runs is None:
                continue
            success = runs["success"]
            rows.append(
                {
                    "suite": suite_label(suite, condition),
                    "method": method,
                    "n": len(runs),
                    "success (%)": success.mean(),
                    "rotation error (deg)": runs["rotation_error_sym_deg"][success].median(),
                    "translation error (mm)": (
                        1e3 * runs["translation_error_sym_m"][success].median()
                    ),
                    "median time (s)": runs["time_s"].median(),
                    "p90 time (s)": runs["time_s"].quantile(0.9),
                    "failed": runs["raised"].sum(),
                    "indistinguishable": runs["open_view"].sum(),
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
    flagged = _flagged(frame)  # once for every row, not suite by suite
    for suite, condition in suite_order(frame):
        here = frame["suite"] == suite
        instances = frame.loc[here, "index"].nunique()
        open_rows = frame.loc[here & flagged, ["index", "method"]]
        open_views = open_rows["index"].nunique()
        rows.append(
            {
                "suite": suite_label(suite, condition),
                "instances": instances,
                "open views": open_views,
                "open (%)": open_views / instances,
                "methods flagging": open_rows["method"].nunique(),
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


def _benchmark_cells(frame: pd.DataFrame, prefix: str, columns: list[str]):
    """(suite label, method, runs) of the suites whose condition starts with ``prefix``,
    in the usual order, with ``columns`` (NaN where a run has none: it raised)."""
    here = frame[frame["condition"].astype(str).str.startswith(prefix)]
    here = here.assign(**{c: float("nan") for c in columns if c not in here})
    cells = by_suite_and_method(here, [*columns, "success", "time_s"])
    for suite, condition in suite_order(here):
        for method in method_order(here):
            runs = cells.get((suite, method))
            if runs is not None:
                yield suite_label(suite, condition), method, runs


def bop_table(frame: pd.DataFrame) -> Table:
    """On BOP instances (conditions ``bop_*``), per suite and method: BOP's recalls."""
    import numpy as np

    from o3d_spectral.harness import pose_metrics as pm

    pandas = require("pandas")
    rows = []
    columns = ["vsd", "mssd_m", "mspd_px", "diameter_m", "image_width_px"]
    for suite, method, runs in _benchmark_cells(frame, "bop_", columns):
        missing = [float("nan")] * len(pm.VSD_TAUS)
        vsd = np.array([v if isinstance(v, list) else missing for v in runs["vsd"]])
        recalls = {
            "AR VSD": pm.vsd_recall(vsd),
            "AR MSSD": pm.mssd_recall(runs["mssd_m"].astype(float), runs["diameter_m"]),
            "AR MSPD": pm.mspd_recall(runs["mspd_px"].astype(float),
                                      runs["image_width_px"].fillna(640)),
        }
        rows.append({"suite": suite, "method": method, "n": len(runs),
                     "AR": pm.average_recall(*recalls.values()), **recalls,
                     "success (%)": runs["success"].astype(bool).mean(),
                     "median time (s)": runs["time_s"].median()})
    result = pandas.DataFrame(rows)
    formats = {"suite": "text", "method": "text", "n": "int", "AR": "f3", "AR VSD": "f3",
               "AR MSSD": "f3", "AR MSPD": "f3", "success (%)": "pct", "median time (s)": "f3"}
    caption = (
        "BOP's average recalls (2019+): VSD (delta 15 mm, tau 0.05-0.5 of the diameter, "
        "thresholds 0.05-0.5), MSSD (0.05-0.5 of the diameter) and MSPD (5-50 px at 640 px "
        "wide), symmetries from models_info.json; AR is their mean. A run that raised "
        "counts as wrong. `success`: the harness's own (symmetry-aware, 5 deg and 1 cm)."
    )
    return Table("bop", caption, result, formats)


def _true(flag) -> bool:
    """A row's flag as read back: ``True``, or ``1.0`` where pandas made the column
    numbers; a missing one (the run raised) is false."""
    return flag is True or flag == 1.0


def pairs_table(frame: pd.DataFrame) -> Table:
    """On scan pairs (condition ``pairs``), per scene and method: both registration
    recalls (RE < 15 deg and TE < 30 cm; RMSE under ``gt.info`` at most 20 cm, missing
    where the scene has no ``gt.info``), mean RE and TE over the pairs recalled by the
    first, time."""
    pandas = require("pandas")
    rows = []
    columns = ["recalled", "rmse_recalled", "re_deg", "te_m"]
    scored = frame.get("rmse_recalled", pandas.Series(dtype=object)).notna()
    with_info = {suite_label(suite, "pairs") for suite in frame.loc[scored, "suite"]}
    for suite, method, runs in _benchmark_cells(frame, "pairs", columns):
        recalled = runs["recalled"].map(_true).astype(bool)
        rmse = runs["rmse_recalled"].map(_true).mean() if suite in with_info else None
        rows.append({"scene": suite, "method": method, "pairs": len(runs),
                     "recall RE/TE (%)": recalled.mean(), "recall RMSE (%)": rmse,
                     "RE (deg)": runs["re_deg"][recalled].astype(float).mean(),
                     "TE (cm)": 100 * runs["te_m"][recalled].astype(float).mean(),
                     "success (%)": runs["success"].astype(bool).mean(),
                     "median time (s)": runs["time_s"].median()})
    result = pandas.DataFrame(rows)
    formats = {"scene": "text", "method": "text", "pairs": "int", "recall RE/TE (%)": "pct",
               "recall RMSE (%)": "pct", "RE (deg)": "f2", "TE (cm)": "f2",
               "success (%)": "pct", "median time (s)": "f3"}
    caption = (
        "Registration recall, both ways papers report it: `recall RE/TE`, pairs with "
        "rotation error < 15 deg and translation error < 30 cm (at the source frame's "
        "origin; FCGF, DGR); `recall RMSE`, the benchmark's own, pairs whose "
        "correspondences the error moves by an RMSE of at most 20 cm, from `gt.info`'s "
        "information matrices (Choi et al. 2015), a dash where the scene has no `gt.info`. "
        "RE and TE: means over the pairs of `recall RE/TE`. `success`: the harness's own "
        "(5 deg, 1 cm at the source's centroid)."
    )
    return Table("pairs", caption, result, formats)
