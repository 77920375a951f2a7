"""Calibrate the confidence: fit its logistic model on part of the development groups and
check it on the rest.

Every instance is registered by ``o3d_spectral.registration_spectral_global(source,
target, voxel)`` at its defaults; the row keeps the pose's evidence
(``result.pose_evidence``), whether it is ambiguous (``result.ambiguity``), the
library's ``result.confidence`` and whether the pose is right: within 5 degrees and 1 cm
at the source's centroid, over the object's symmetries (``harness.metrics``,
``harness.real.case_score``); every pose of a wrong-object pair is wrong.

Groups (each instance a *unit*; a real pair turned several ways is one unit):

* ``partial``, ``occluded``, ``cluttered``: a bundled model against a depth view of it
  (alone, half hidden, in a tabletop scene; ``synthetic.scenes.make_instance``);
* ``crop_in_scene``: the object's own points cut out of a cluttered view by its label, at
  a random pose, against the whole view (a crop whose sensor is unknown);
* ``half_crop``: a model against a copy of itself cut by a plane near its centroid, at a
  random pose (a crop hides no surface: its right pose must not be warned about);
* ``turntable_30`` / ``_45`` / ``_90`` / ``_135`` / ``_150``: two depth views of a model,
  the turntable turned that far between them (``synthetic.turntable``);
* ``dragon``: the bundled dragon scans 24-168 degrees apart (``harness.real``), each from
  ``--rotations`` random rotations;
* ``ycbv_crop``, ``ycbv_frame``: the bundled YCB-Video frame's objects against their crop
  and against the whole frame (``harness.real``), each from ``--rotations`` rotations;
* ``wrong_object``: a model against a depth view (partial or occluded) of another model.

Split: within each group, the units are shuffled with ``--seed`` and the first half (odd
counts: one more) fit the model, the rest are held back. The model: logistic regression
on the features of ``o3d_spectral.evidence.confidence.features``, standardised, with an L2
penalty ``--penalty`` on the weights (not the intercept); its coefficients are printed in
raw units, as ``o3d_spectral.evidence.confidence`` holds them.

On the held-back part it reports, for the refitted model and for the library's own
``result.confidence``: the AUROC between right and wrong poses, the warning's precision
(share of warned poses that are wrong) and recall (share of wrong poses warned) at
confidence < 0.5, the Brier score; a table per group; and a reliability diagram
(predicted against observed, in bins of 0.1).

``--split object`` (``group``) instead holds back each object (each group) in turn and
refits on the rest (leave one out): a fold's figures say how the confidence does on an
object (a kind of data) it was not fitted on; ``folds.csv`` holds each fold's figures and
``summary.csv`` the pooled held-back ones (with ``--docs``, also
``docs/data/calibrate_confidence_{object,group}_{folds,summary}.csv`` and
``calibrate_confidence_silent.csv``, and the library's reliability diagram per group,
``docs/img/confidence_reliability_groups.png``). ``--instances k`` draws other instances of
every group (other seeds, other rotations of the real pairs). ``silent.csv`` counts the
library's calls as they came back: wrong poses with confidence >= 0.5 and no warning of
any kind, and right poses carrying a warning (of any kind, and about the pose).

Writes to ``--out``: ``rows.csv`` (one row per call), ``summary.csv`` (pooled figures),
``reliability_groups.png`` (the library's confidence against the share of right poses,
per group),
``groups.csv`` (per group, held-back), ``coefficients.json`` (the refit) and
``reliability.png``; with ``--docs``, also ``docs/data/calibrate_confidence_*.csv``, the
coefficients (``docs/data/calibrate_confidence_coefficients.json``) and
``docs/img/confidence_reliability.png``. ``--rows FILE`` refits from a ``rows.csv``
without registering again.

Usage: python eval/calibrate_confidence.py --out out/calibrate_confidence [--per-group 12]
       [--rotations 3] [--groups partial ...] [--seed 0] [--penalty 0.03] [--docs]
       [--rows out/calibrate_confidence/rows.csv] [--split half|object|group]
       [--instances 0]
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from itertools import zip_longest
from pathlib import Path

import numpy as np
import open3d as o3d
from scipy.optimize import minimize

import o3d_spectral
from o3d_spectral.evidence import confidence as confidence_model
from o3d_spectral.evidence.pose import PoseEvidence
from o3d_spectral.harness import real
from o3d_spectral.harness.errors import symmetric_rotation_error, symmetric_translation_error
from o3d_spectral.harness.metrics import instance_score
from o3d_spectral.harness.writers import write_rows
from o3d_spectral.synthetic.models import model_names
from o3d_spectral.synthetic.sampling import model_cloud, point_cloud, rigid, sample_rotation
from o3d_spectral.synthetic.scenes import make_instance
from o3d_spectral.synthetic.symmetry import model_symmetry
from o3d_spectral.synthetic.turntable import turntable_pair

ROOT = Path(__file__).resolve().parents[1]
VOXEL = 0.008
TURNTABLE = {f"turntable_{angle}": angle for angle in (30, 45, 90, 135, 150)}
#: The dragon scan pairs' steps, degrees (round robin over them).
DRAGON_STEPS = (24, 48, 72, 96, 120, 144, 168)
#: The YCB-Video frame's objects, against their crop and against the whole frame.
YCBV_GROUPS = ("ycbv_crop", "ycbv_frame")
GROUPS = ("partial", "occluded", "cluttered", "crop_in_scene", "half_crop", *TURNTABLE,
          "dragon", *YCBV_GROUPS, "wrong_object")
#: The evidence columns of a row, as ``result.pose_evidence`` names them.
EVIDENCE = ("fit", "target_fit", "plane_distance", "normal_agreement", "free_space",
            "rival_fit", "ambiguous", "rival_self_match", "two_views", "motion_support")
#: The kinds (:func:`kind_of`) of the warnings about the returned pose (the others are
#: about the inputs or the law's convergence).
POSE_WARNINGS = ("low_confidence", "ambiguous", "underdetermined")
#: Bins of the reliability diagram.
BINS = 10
#: Elevation of the turntable pairs' views, degrees.
ELEVATION = 30.0
#: ``--instances k`` adds k times this to every synthetic instance's seed (units < 500).
INSTANCE_SHIFT = 500_000

Score = Callable[[np.ndarray], tuple[float, float, bool]]


@dataclass
class Case:
    group: str
    unit: str
    source: o3d.geometry.PointCloud
    target: o3d.geometry.PointCloud
    voxel: float
    score: Score


def never_right(_: np.ndarray) -> tuple[float, float, bool]:
    """A wrong-object pair: every pose is wrong."""
    return math.nan, math.nan, False


def cases(group: str, n: int, rotations: int, instances: int = 0) -> Iterator[Case]:
    """The first ``n`` units of ``group`` (see the module docstring); ``instances`` > 0
    draws other instances of the synthetic groups and other rotations of the real ones."""
    shift = INSTANCE_SHIFT * instances
    names = model_names()
    picks = [names[i % len(names)] for i in range(n)]
    if group in ("partial", "occluded", "cluttered"):
        for i, name in enumerate(picks):
            inst = make_instance(group, name, rng=np.random.default_rng(10_000 + shift + i))
            yield Case(group, f"{group}_{i}_{name}", inst.source, inst.target, VOXEL,
                       instance_score(inst))
    elif group == "crop_in_scene":
        for i, name in enumerate(picks):
            yield crop_in_scene(i, name, shift)
    elif group == "half_crop":
        for i, name in enumerate(picks):
            yield half_crop(i, name, shift)
    elif group in TURNTABLE:
        for i, name in enumerate(picks):
            pair = turntable_pair(name, TURNTABLE[group], ELEVATION,
                                  np.random.default_rng(20_000 + shift + i))
            yield Case(group, f"{group}_{i}_{name}", pair.source, pair.target, VOXEL,
                       instance_score(pair))
    elif group in ("dragon", *YCBV_GROUPS):  # the dragon's: round robin over the steps
        by_step = ([real.dragon_cases(step) for step in DRAGON_STEPS] if group == "dragon"
                   else [real.load_cases([group])])
        ordered = [c for row in zip_longest(*by_step) for c in row if c is not None]
        for case in ordered[:n]:
            for r in range(rotations):
                turned, _ = real.randomly_rotated(
                    case, real.rotation_seed(case.name, r + rotations * instances))
                yield Case(group, case.name, turned.source, turned.target,
                           real.VOXEL_SIZES.get(case.group, real.DRAGON_VOXEL),
                           real.case_score(turned))
    elif group == "wrong_object":
        for i, name in enumerate(picks):
            other = names[(names.index(name) + 1 + i // len(names)) % len(names)]
            condition = ("partial", "occluded")[i % 2]
            inst = make_instance(condition, other, rng=np.random.default_rng(30_000 + shift + i))
            points, normals = (a.copy() for a in model_cloud(name, 6000))
            yield Case(group, f"{name}_on_{other}_{i}", point_cloud(points, normals),
                       inst.target, VOXEL, never_right)
    else:
        raise SystemExit(f"error: unknown group {group!r}; known: {', '.join(GROUPS)}")


def crop_in_scene(i: int, name: str, shift: int = 0) -> Case:
    """The object's points cut out of a cluttered view, at a random pose, against it."""
    inst = make_instance("cluttered", name, rng=np.random.default_rng(40_000 + shift + i))
    points = np.asarray(inst.target.points)[inst.target_labels == 0]
    rng = np.random.default_rng(41_000 + shift + i)
    presentation = rigid(sample_rotation(rng), rng.uniform(-0.1, 0.1, size=3))
    source = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points)).transform(presentation)
    truth = np.linalg.inv(presentation)
    symmetry = inst.symmetry.transformed(presentation @ inst.T_gt)
    return Case("crop_in_scene", f"crop_in_scene_{i}_{name}", source, inst.target, VOXEL,
                symmetric_score(truth, symmetry, np.asarray(source.points).mean(axis=0)))


def half_crop(i: int, name: str, shift: int = 0) -> Case:
    """A model against a copy of itself cut by a plane within a fifth of its extent of its
    centroid, at a random pose."""
    rng = np.random.default_rng(50_000 + shift + i)
    points, normals = (a.copy() for a in model_cloud(name, 6000))
    direction = rng.normal(size=3)
    direction /= np.linalg.norm(direction)
    along = (points - points.mean(axis=0)) @ direction
    keep = along > rng.uniform(-0.2, 0.2) * np.abs(along).max()
    motion = rigid(sample_rotation(rng), rng.uniform(-0.1, 0.1, size=3))
    target = point_cloud(points[keep] @ motion[:3, :3].T + motion[:3, 3],
                         normals[keep] @ motion[:3, :3].T)
    return Case("half_crop", f"half_crop_{i}_{name}", point_cloud(points, normals), target,
                VOXEL, symmetric_score(motion, model_symmetry(name), points.mean(axis=0)))


def symmetric_score(truth: np.ndarray, symmetry, centre: np.ndarray) -> Score:
    """Symmetry-aware errors against ``truth`` (4, 4); right under 5 deg and 1 cm."""

    def score(T: np.ndarray) -> tuple[float, float, bool]:
        rotation = symmetric_rotation_error(T, truth, symmetry)
        translation = symmetric_translation_error(T, truth, symmetry, center=centre)
        return rotation, translation, real.is_success(rotation, translation)

    return score


def register(case: Case) -> dict:
    """One call's row: the group, unit, outcome, evidence and the library's confidence."""
    start = time.perf_counter()
    result = o3d_spectral.registration_spectral_global(case.source, case.target, case.voxel)
    seconds = time.perf_counter() - start
    rotation, translation, right = case.score(np.asarray(result.transformation))
    evidence = result.pose_evidence
    row = {"group": case.group, "unit": case.unit, "right": int(right),
           "rotation_error_deg": rotation, "translation_error_m": translation,
           "seconds": seconds, "confidence": result.confidence,
           "warned": int(any("may be wrong" in w for w in result.warnings)),
           "warnings": len(result.warnings),
           "pose_warnings": sum(kind_of(w) in POSE_WARNINGS for w in result.warnings),
           "warning_kinds": " ".join(kind_of(w) for w in result.warnings),
           "notes": len(result.notes),
           "source_view": int(result.source_reading.view is not None),
           "ambiguity_deg": "" if result.ambiguity is None else result.ambiguity,
           "other_right": "" if result.ambiguous_transformation is None
           else int(case.score(result.ambiguous_transformation)[2]),
           "free_motions": " ".join(
               f"{m.kind}:{m.extent:.4g}:{'symmetry' if m.symmetric else 'unfixed'}"
               for m in evidence.free_motions)}
    row.update({name: getattr(evidence, name) for name in EVIDENCE})
    row["free_space"] = "" if evidence.free_space is None else evidence.free_space
    row["ambiguous"], row["two_views"] = int(evidence.ambiguous), int(evidence.two_views)
    return row


def kind_of(warning: str) -> str:
    """A warning's kind, one word (``o3d_spectral.evidence.diagnostics``)."""
    for key, kind in (("control law stopped", "not_converged"), ("oriented again", "reoriented"),
                      ("read two-sided", "two_sided"), ("nearly all alike", "flat"),
                      ("low confidence", "low_confidence"), ("ambiguous", "ambiguous"),
                      ("underdetermined", "underdetermined")):
        if key in warning:
            return kind
    return "other"


def read_rows(path: Path) -> list[dict]:
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def optional(value: str | None) -> float | None:
    """A stored number, or None where the cell is empty."""
    return None if value in ("", None) else float(value)


def design(rows: list[dict]) -> np.ndarray:
    """The model's features of each row, (N, F) in ``confidence_model.FEATURES`` order."""
    out = []
    for row in rows:
        evidence = PoseEvidence(
            float(row["fit"]), float(row["target_fit"]), float(row["plane_distance"]),
            float(row["normal_agreement"]), optional(row["free_space"]),
            float(row["rival_fit"]), bool(int(row["ambiguous"])),
            float(row["rival_self_match"]), bool(int(row["two_views"])),
            float(row["motion_support"]))
        values = confidence_model.features(evidence)
        out.append([values[name] for name in confidence_model.FEATURES])
    return np.asarray(out, dtype=np.float64)


def fit_logistic(X: np.ndarray, y: np.ndarray, penalty: float) -> tuple[float, np.ndarray]:
    """L2-penalised logistic regression on standardised ``X`` (N, F); the intercept and
    the weights (F,) in raw units."""
    mean, scale = X.mean(axis=0), X.std(axis=0)
    scale[scale == 0.0] = 1.0  # a constant feature: weight 0 under the penalty
    Z = np.c_[np.ones(len(X)), (X - mean) / scale]

    def loss(w: np.ndarray) -> tuple[float, np.ndarray]:
        z = Z @ w
        value = np.sum(np.logaddexp(0.0, z) - y * z) + penalty * np.sum(w[1:] ** 2)
        grad = Z.T @ (1.0 / (1.0 + np.exp(-z)) - y)
        grad[1:] += 2.0 * penalty * w[1:]
        return float(value), grad

    w = minimize(loss, np.zeros(Z.shape[1]), jac=True, method="L-BFGS-B").x
    weights = w[1:] / scale
    return float(w[0] - np.sum(weights * mean)), weights


def predict(bias: float, weights: np.ndarray, X: np.ndarray) -> np.ndarray:
    return 1.0 / (1.0 + np.exp(-np.clip(bias + X @ weights, -500.0, 500.0)))


def library_confidence(X: np.ndarray, corroborated: np.ndarray) -> np.ndarray:
    """The library's confidence at the features ``X`` (N, F), with its constants; 0 where
    no point corroborates the pose (``corroborated`` (N,) False: a fit of 0)."""
    weights = np.array([confidence_model.COEFFICIENTS[n] for n in confidence_model.FEATURES])
    return predict(confidence_model.BIAS, weights, X) * corroborated


def corroborated(rows: list[dict]) -> np.ndarray:
    """Where a row's pose has a fit over 0 (``confidence_model.confidence`` is 0 where
    not), (N,) bool."""
    return np.array([float(r["fit"]) > 0.0 for r in rows])


def auroc(p: np.ndarray, right: np.ndarray) -> float:
    """Probability that a right pose scores above a wrong one (ties count half)."""
    pos, neg = p[right == 1], p[right == 0]
    if len(pos) == 0 or len(neg) == 0:
        return math.nan
    greater = (pos[:, None] > neg[None, :]).mean()
    ties = (pos[:, None] == neg[None, :]).mean()
    return float(greater + 0.5 * ties)


def figures(p: np.ndarray, right: np.ndarray) -> dict:
    """n, wrong, AUROC, the warning's precision and recall at WARN_BELOW, Brier."""
    warned, wrong = p < confidence_model.WARN_BELOW, right == 0
    hits = int(np.sum(warned & wrong))
    return {"n": len(p), "wrong": int(wrong.sum()), "warned": int(warned.sum()),
            "warned_wrong": hits, "warned_right": int(np.sum(warned & ~wrong)),
            "auroc": auroc(p, right),
            "precision": hits / warned.sum() if warned.any() else math.nan,
            "recall": hits / wrong.sum() if wrong.any() else math.nan,
            "brier": float(np.mean((p - right) ** 2)) if len(p) else math.nan}


def split(rows: list[dict], seed: int) -> np.ndarray:
    """True where a row is held back: within each group, the units shuffled with
    ``seed``, all but the first half (rounded up)."""
    rng = np.random.default_rng(seed)
    held = np.zeros(len(rows), dtype=bool)
    for group in dict.fromkeys(r["group"] for r in rows):
        units = sorted({r["unit"] for r in rows if r["group"] == group})
        rng.shuffle(units)
        back = set(units[(len(units) + 1) // 2:])
        held |= np.array([r["group"] == group and r["unit"] in back for r in rows])
    return held


def fold_of(row: dict, by: str) -> str:
    """The row's fold: its group, or its object (the source's model; ``dragon`` for the
    real dragon scans)."""
    if by == "group":
        return row["group"]
    if row["group"] == "dragon":
        return "dragon"
    unit = row["unit"]
    if row["group"] == "wrong_object":
        return unit.split("_on_")[0]
    return next(name for name in model_names() if unit.endswith("_" + name))


def silent(rows: list[dict], right: np.ndarray) -> dict:
    """The library's calls as they came back: wrong poses with confidence >= 0.5 and no
    warning of any kind (silent), right poses with a warning of any kind, and with a
    warning about the pose (:data:`POSE_WARNINGS`); of the right poses warned as
    ambiguous, those whose other pose (``result.ambiguous_transformation``) is wrong: a
    wrong answer the data fit as well, which the warning rightly names (rows that
    recorded it)."""
    confident = np.array([float(r["confidence"]) >= confidence_model.WARN_BELOW for r in rows])
    warned = np.array([int(r["warnings"]) > 0 for r in rows])
    about_pose = np.array([int(r["pose_warnings"]) > 0 for r in rows])
    ambiguous = np.array(["ambiguous" in r["warning_kinds"].split() for r in rows])
    other_wrong = np.array([str(r.get("other_right", "")) == "0" for r in rows])
    wrong = right == 0
    return {"calls": len(rows), "wrong": int(wrong.sum()),
            "silent_wrong": int(np.sum(wrong & confident & ~warned)),
            "right": int((~wrong).sum()), "right_warned": int(np.sum(~wrong & warned)),
            "right_pose_warned": int(np.sum(~wrong & about_pose)),
            "right_ambiguous": int(np.sum(~wrong & ambiguous)),
            "right_ambiguous_other_wrong": int(np.sum(~wrong & ambiguous & other_wrong))}


def leave_one_out(rows: list[dict], X: np.ndarray, right: np.ndarray,
                  args: argparse.Namespace) -> int:
    """Refit on all folds but one and predict it, for each fold (``args.split``); write
    each fold's figures (``folds.csv``), the pooled held-back figures of the refits and
    of the library (``summary.csv``), and the reliability of the pooled refits."""
    labels = np.array([fold_of(r, args.split) for r in rows])
    seen = corroborated(rows)
    pooled = np.full(len(rows), np.nan)
    folds = []
    for label in dict.fromkeys(labels):
        out = labels == label
        bias, weights = fit_logistic(X[~out], right[~out].astype(float), args.penalty)
        pooled[out] = predict(bias, weights, X[out]) * seen[out]
        folds.append({"fold": label, **figures(pooled[out], right[out])})
    library = library_confidence(X, seen)
    summary = [{"confidence": name, "part": f"each {args.split} held back",
                **figures(p, right)} for name, p in (("refit", pooled), ("library", library))]
    bins = reliability(pooled, right)
    write_rows(args.out / "folds.csv", [rounded(r) for r in folds])
    write_rows(args.out / "summary.csv", [rounded(r) for r in summary])
    write_rows(args.out / "reliability.csv", [rounded(r) for r in bins])
    plot(bins, args.out / "reliability.png", f"confidence, each {args.split} held back")
    if args.docs:
        for name in ("folds", "summary"):
            write_rows(ROOT / "docs" / "data" / f"calibrate_confidence_{args.split}_{name}.csv",
                       read_rows(args.out / f"{name}.csv"))
        if "warnings" in rows[0]:
            write_rows(ROOT / "docs" / "data" / "calibrate_confidence_silent.csv",
                       read_rows(args.out / "silent.csv"))
    print(f"| {args.split} held back | n | wrong | AUROC | precision | recall | Brier |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for r in folds + summary:
        print(f"| {r.get('fold', r.get('confidence'))} | {r['n']} | {r['wrong']} "
              f"| {r['auroc']:.3f} | {r['precision']:.2f} | {r['recall']:.2f} "
              f"| {r['brier']:.3f} |")
    if "warnings" in rows[0]:
        print(silent(rows, right))
    return 0


def reliability(p: np.ndarray, right: np.ndarray) -> list[dict]:
    """Per bin of predicted confidence: its range, count, mean prediction and observed
    share of right poses."""
    edges = np.linspace(0.0, 1.0, BINS + 1)
    index = np.minimum(np.digitize(p, edges) - 1, BINS - 1)
    return [{"low": edges[b], "high": edges[b + 1], "n": int(np.sum(index == b)),
             "predicted": float(p[index == b].mean()) if np.any(index == b) else math.nan,
             "observed": float(right[index == b].mean()) if np.any(index == b) else math.nan}
            for b in range(BINS)]


def draw_reliability(ax, bins: list[dict]) -> None:
    """The reliability diagram of ``bins`` (:func:`reliability`) on ``ax``: the diagonal,
    each bin's mean confidence against its share of right poses with its count beside it,
    and the warning's threshold."""
    ax.plot([0, 1], [0, 1], color="0.6", linestyle="--", label="calibrated")
    shown = [b for b in bins if b["n"]]
    ax.plot([b["predicted"] for b in shown], [b["observed"] for b in shown], marker="o",
            label="held-back calls")
    for b in shown:
        ax.annotate(str(b["n"]), (b["predicted"], b["observed"]), textcoords="offset points",
                    xytext=(4, -10), fontsize=7)
    ax.axvline(confidence_model.WARN_BELOW, color="tab:red", linewidth=0.8)


def plot(bins: list[dict], path: Path, title: str) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(4.5, 4.5))
    draw_reliability(ax, bins)
    ax.set(xlim=(0, 1), ylim=(0, 1), xlabel="predicted confidence (bin mean)",
           ylabel="observed share of right poses", title=title)
    ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_groups(rows: list[dict], p: np.ndarray, right: np.ndarray, path: Path) -> None:
    """A reliability diagram per group: the library's confidence binned by tenths against
    the share of right poses, each bin's count beside it."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    groups = list(dict.fromkeys(r["group"] for r in rows))
    columns = 4
    lines = -(-len(groups) // columns)
    fig, axes = plt.subplots(lines, columns, figsize=(3.0 * columns, 3.0 * lines),
                             sharex=True, sharey=True, squeeze=False)
    for ax, group in zip(axes.flat, groups, strict=False):
        mask = np.array([r["group"] == group for r in rows])
        draw_reliability(ax, reliability(p[mask], right[mask]))
        ax.set(xlim=(0, 1), ylim=(-0.05, 1.05),
               title=f"{group} ({int(mask.sum())}, {int((right[mask] == 0).sum())} wrong)")
        ax.title.set_fontsize(8)
    for ax in axes.flat[len(groups):]:
        ax.set_visible(False)
    fig.supxlabel("confidence (bin mean)")
    fig.supylabel("share of right poses")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)


def rounded(row: dict) -> dict:
    """``row`` as written to a CSV file: floats with 6 decimals, the rest as text."""
    return {k: (f"{v:.6f}" if isinstance(v, float) else str(v)) for k, v in row.items()}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--groups", nargs="+", default=list(GROUPS), choices=GROUPS)
    parser.add_argument("--per-group", type=int, default=12)
    parser.add_argument("--rotations", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--penalty", type=float, default=0.03)
    parser.add_argument("--rows", type=Path, help="refit from this rows.csv")
    parser.add_argument("--split", choices=("half", "object", "group"), default="half",
                        help="hold back half of each group's units, or each object (each "
                             "group) in turn, fitted on the rest")
    parser.add_argument("--instances", type=int, default=0,
                        help="draw other instances (0: the calibration's own)")
    parser.add_argument("--docs", action="store_true",
                        help="also write docs/data/calibrate_confidence_*.csv and the figure")
    args = parser.parse_args(argv)
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    args.out.mkdir(parents=True, exist_ok=True)
    if args.rows is not None:
        rows = read_rows(args.rows)
    else:
        rows = []
        for group in args.groups:
            for case in cases(group, args.per_group, args.rotations, args.instances):
                row = register(case)
                rows.append(row)
                print(f"{group:14s} {case.unit:40s} right={row['right']} "
                      f"confidence={row['confidence']:.3f} {row['seconds']:.2f} s", flush=True)
        stored = np.array([float(r["confidence"]) for r in rows])
        model = library_confidence(design(rows), corroborated(rows))
        rows = [rounded(r) for r in rows]  # as stored: a refit from the file is the same
        write_rows(args.out / "rows.csv", rows)
        # the calls' own result.confidence is the library's model of their features
        if not np.allclose(model, stored, atol=1e-9):
            raise AssertionError("result.confidence differs from the model of its features")
    right = np.array([int(r["right"]) for r in rows])
    X = design(rows)
    library = library_confidence(X, corroborated(rows))
    plot_groups(rows, library, right, args.out / "reliability_groups.png")
    if args.docs and args.split != "half":
        plot_groups(rows, library, right,
                    ROOT / "docs" / "img" / "confidence_reliability_groups.png")
    if "warnings" in rows[0]:
        write_rows(args.out / "silent.csv", [rounded(silent(rows, right))])
    if args.split != "half":
        return leave_one_out(rows, X, right, args)
    held = split(rows, args.seed)
    refit = library.copy()
    fitted = len(set(right[~held])) == 2
    if fitted:
        bias, weights = fit_logistic(X[~held], right[~held].astype(float), args.penalty)
        refit = predict(bias, weights, X) * corroborated(rows)
        coefficients = {"bias": bias, **dict(zip(confidence_model.FEATURES, weights.tolist(),
                                                 strict=True))}
        (args.out / "coefficients.json").write_text(json.dumps(coefficients, indent=2) + "\n")
        print("refit coefficients (raw units):")
        print(f"BIAS = {bias:.4f}")
        for name, w in zip(confidence_model.FEATURES, weights, strict=True):
            print(f'    "{name}": {w:.4f},')
    else:
        print("the fitting part holds one class only: no refit (library figures only)")
    summary = []
    for name, p in (("library", library), ("refit", refit)):
        for part, mask in (("held back", held), ("fitting", ~held)):
            summary.append({"confidence": name, "part": part, **figures(p[mask], right[mask])})
    groups = []
    for group in dict.fromkeys(r["group"] for r in rows):
        mask = held & np.array([r["group"] == group for r in rows])
        groups.append({"group": group, **figures(library[mask], right[mask]),
                       "mean_confidence": float(library[mask].mean()) if mask.any() else math.nan})
    bins = reliability(library[held], right[held])
    write_rows(args.out / "summary.csv", [rounded(r) for r in summary])
    write_rows(args.out / "groups.csv", [rounded(r) for r in groups])
    write_rows(args.out / "reliability.csv", [rounded(r) for r in bins])
    title = "confidence on held-back calls"
    plot(bins, args.out / "reliability.png", title)
    if args.docs:
        for name in ("summary", "groups", "reliability"):
            write_rows(ROOT / "docs" / "data" / f"calibrate_confidence_{name}.csv",
                      read_rows(args.out / f"{name}.csv"))
        plot(bins, ROOT / "docs" / "img" / "confidence_reliability.png", title)
        if fitted:
            (ROOT / "docs" / "data" / "calibrate_confidence_coefficients.json").write_text(
                (args.out / "coefficients.json").read_text())
    print()
    print("| confidence | part | n | wrong | AUROC | precision | recall | Brier |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for r in summary:
        print(f"| {r['confidence']} | {r['part']} | {r['n']} | {r['wrong']} | {r['auroc']:.3f} "
              f"| {r['precision']:.2f} | {r['recall']:.2f} | {r['brier']:.3f} |")
    print()
    print("| group (held back) | n | wrong | warned wrong | warned right | Brier |")
    print("| --- | --- | --- | --- | --- | --- |")
    for r in groups:
        print(f"| {r['group']} | {r['n']} | {r['wrong']} | {r['warned_wrong']} "
              f"| {r['warned_right']} | {r['brier']:.3f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
