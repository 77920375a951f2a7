"""Benchmark: time against raw density at a fixed voxel, spectral and lean FPFH-RANSAC.

Each case is a turntable pair of a bundled model (``o3d_spectral.synthetic.turntable``:
two depth views ``--angle`` degrees apart at ``--elevation`` degrees, each in its own
camera frame) scanned by the same camera at ``--scales`` k = 1, 2, 4: the image's width,
height and focal lengths times k, the principal point kept at the same spot of the image
(``k (c + 0.5) - 0.5``), and the disparity step times k so that the depth quantisation is
the same. A scale k gives k^2 times the points on the same surfaces (1x, 4x, 16x), from
the same seed (200 + the model's index, as ``eval/bench_speed.py``'s turntable groups):
the same azimuth, the same poses. The voxel (``--voxel``, 8 mm) is fixed.

Methods, one thread each, at their defaults, on the same instances in the same run:

* spectral: ``o3d_spectral.registration_spectral_global(source, target, voxel,
  search=GlobalSearchOption(workers=1))``; its ``result.stage_times`` are kept per stage
  (prepare, candidates, confirm, sweep, climbs, ascent, polish; a stage skipped is 0 s).
* lean FPFH-RANSAC: the harness's ``fpfh_ransac_lean`` (``bench_speed.harness_call``).

Each instance is timed ``--repeats`` times, the methods in turn, with
``time.perf_counter`` around the call only (scanning and scoring are outside); the median
of its times (and, for spectral, of each stage's) is kept and the first call's pose is
scored symmetry-aware, 5 deg and 1 cm (``bench_speed``'s turntable score). One untimed call
of each method on the first instance warms up FFT plans and caches first.

Writes to ``--out``: ``density.csv`` (one row per instance, scale and method: points,
seconds, errors, success, stage seconds), ``summary.csv`` and ``summary.md`` (per points
multiplier and method: median points, median seconds, the median over instances of the
time's ratio to the same instance at 1x, success; spectral's median stage seconds, and the
median over instances of each stage's seconds added since 1x and of its ratio to 1x) and
``density.png`` (median seconds against the points multiplier, log-x, both methods, the
ratios to 1x annotated). Prints the Markdown tables; progress goes to stderr.

Usage: python eval/bench_density.py --out out/bench_density
       [--limit 6] [--repeats 3] [--scales 1 2 4] [--angle 45] [--elevation 20]
       [--voxel 0.008]
"""

from __future__ import annotations

# isort: off
import bench_speed as speed  # first: it sets one thread before numpy and Open3D load
# isort: on

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

import o3d_spectral
from o3d_spectral.common.stages import GLOBAL_STAGES
from o3d_spectral.harness.writers import write_figure, write_rows
from o3d_spectral.plots import pyplot
from o3d_spectral.synthetic.instance import SceneOptions
from o3d_spectral.synthetic.models import model_names
from o3d_spectral.synthetic.sensor import CameraIntrinsics
from o3d_spectral.synthetic.turntable import turntable_pair

SPECTRAL = "spectral_global"
METHODS = (SPECTRAL, speed.REFERENCE)
LABELS = {SPECTRAL: "spectral global", speed.REFERENCE: "lean FPFH-RANSAC"}
#: Seed of the first model's pair; model ``i`` draws from ``SEED_BASE + i``.
SEED_BASE = 200


@dataclasses.dataclass
class Case:
    """One model's pair at one scale: the timed task and what identifies its scan."""

    model: str
    scale: int
    azimuth_deg: float
    task: speed.Task

    @property
    def multiplier(self) -> int:
        """Points per surface area relative to scale 1 (``scale ** 2``)."""
        return self.scale ** 2


def scaled_options(scale: int) -> SceneOptions:
    """The default camera with ``scale`` times the pixels along each image axis.

    Parameters
    ----------
    scale : int
        Linear factor k of the image size (pixels) and the focal lengths (pixels).

    Returns
    -------
    SceneOptions
        Intrinsics of k times the width, height and focal lengths, the principal point at
        the same spot of the image; the depth noise with k times the disparity step
        (pixels), so that its depth quantisation (metres) is unchanged.
    """
    base, defaults = CameraIntrinsics(), SceneOptions()
    intrinsics = CameraIntrinsics(
        width=base.width * scale, height=base.height * scale,
        fx=base.fx * scale, fy=base.fy * scale,
        cx=scale * (base.cx + 0.5) - 0.5, cy=scale * (base.cy + 0.5) - 0.5)
    noise = dataclasses.replace(defaults.noise,
                                disparity_step=defaults.noise.disparity_step * scale)
    return SceneOptions(intrinsics=intrinsics, noise=noise)


def make_case(index: int, model: str, scale: int, angle: float, elevation: float,
              voxel: float) -> Case:
    """The turntable pair of ``model`` (seed :data:`SEED_BASE` + ``index``) at ``scale``.

    Parameters
    ----------
    index : int
        The model's position in :func:`model_names`; seeds the scan and the harness method.
    model : str
        A bundled model.
    scale : int
        Linear image scale (:func:`scaled_options`).
    angle, elevation : float
        Turntable angle between the views and camera elevation, degrees.
    voxel : float
        Voxel size of both methods, metres.
    """
    pair = turntable_pair(model, angle, elevation, np.random.default_rng(SEED_BASE + index),
                          scaled_options(scale))
    task = speed.Task(f"density_{scale ** 2}x", f"{model}_{scale ** 2}x", pair.source,
                      pair.target, voxel, index, speed.instance_score(pair))
    return Case(model, scale, float(pair.metadata["azimuth_deg"]), task)


def spectral_call(task: speed.Task) -> tuple[np.ndarray, dict[str, float]]:
    """The global spectral call on one thread: its pose (4, 4) and stage seconds."""
    result = o3d_spectral.registration_spectral_global(
        task.source, task.target, task.voxel,
        search=o3d_spectral.GlobalSearchOption(workers=1))
    stages = {stage: result.stage_times.get(stage, 0.0) for stage in GLOBAL_STAGES}
    return np.asarray(result.transformation), stages


def reference_call(task: speed.Task) -> tuple[np.ndarray, dict[str, float]]:
    """The harness's lean FPFH-RANSAC: its pose (4, 4) and no stage seconds."""
    transformation, _ = speed.harness_call(speed.REFERENCE)(task)
    return transformation, {}


CALLS = {SPECTRAL: spectral_call, speed.REFERENCE: reference_call}


def run_case(case: Case, repeats: int) -> list[dict]:
    """One row per method: median seconds (and stage seconds) of ``repeats`` timed calls,
    the methods in turn, and the score of the first call's pose."""
    seconds: dict[str, list[float]] = {m: [] for m in METHODS}
    stages: dict[str, list[dict[str, float]]] = {m: [] for m in METHODS}
    poses: dict[str, np.ndarray] = {}
    for _ in range(repeats):
        for method in METHODS:
            start = time.perf_counter()
            transformation, stage_times = CALLS[method](case.task)
            seconds[method].append(time.perf_counter() - start)
            stages[method].append(stage_times)
            poses.setdefault(method, transformation)
    rows = []
    for method in METHODS:
        rotation, translation, success = case.task.score(poses[method])
        row = {"model": case.model, "scale": case.scale, "multiplier": case.multiplier,
               "azimuth_deg": case.azimuth_deg, "method": method, "voxel_m": case.task.voxel,
               "source_points": len(case.task.source.points),
               "target_points": len(case.task.target.points),
               "seconds": float(np.median(seconds[method])),
               "rotation_error_deg": rotation, "translation_error_m": translation,
               "success": bool(success)}
        for stage in GLOBAL_STAGES:
            values = [s[stage] for s in stages[method] if stage in s]
            row[f"{stage}_s"] = float(np.median(values)) if values else float("nan")
        rows.append(row)
    return rows


def to_first(rows: list[dict], method: str, column: str,
             how: str = "ratio") -> dict[int, list[float]]:
    """Per multiplier, each model's ``column`` against the same model's at the smallest
    multiplier, for ``method``'s rows: their ratio (``how="ratio"``; NaN where the first
    is 0) or their difference (``how="difference"``)."""
    picked = [r for r in rows if r["method"] == method]
    first = min(r["multiplier"] for r in picked)
    base = {r["model"]: r[column] for r in picked if r["multiplier"] == first}
    out: dict[int, list[float]] = {}
    for r in picked:
        value, reference = r[column], base[r["model"]]
        if how == "difference":
            out.setdefault(r["multiplier"], []).append(value - reference)
        else:
            out.setdefault(r["multiplier"], []).append(
                value / reference if reference > 0 else float("nan"))
    return out


def median(values: list[float]) -> float:
    """The median of the values that are not NaN; NaN if none is."""
    kept = [v for v in values if not np.isnan(v)]
    return float(np.median(kept)) if kept else float("nan")


def stage_columns(rows: list[dict], method: str, multiplier: int) -> dict[str, float]:
    """``method``'s stage figures at ``multiplier``, per stage: the median seconds, and the
    median over the models of the seconds added to, and the ratio to, the first
    multiplier's (all NaN for a method without stages)."""
    picked = [r for r in rows if r["method"] == method and r["multiplier"] == multiplier]
    out = {}
    for stage in GLOBAL_STAGES:
        column = f"{stage}_s"
        out[f"{stage}_median_s"] = median([r[column] for r in picked])
        out[f"{stage}_median_added_s"] = median(
            to_first(rows, method, column, "difference")[multiplier])
        out[f"{stage}_median_ratio_to_1x"] = median(to_first(rows, method, column)[multiplier])
    return out


def summarise(rows: list[dict]) -> list[dict]:
    """Per points multiplier and method: n, median points (source and target), median
    seconds, the median and largest ratio of an instance's seconds to its first
    multiplier's, success rate, and (spectral) the stage figures of
    :func:`stage_columns`."""
    out = []
    for method in METHODS:
        ratios = to_first(rows, method, "seconds")
        for multiplier in sorted(ratios):
            picked = [r for r in rows
                      if r["method"] == method and r["multiplier"] == multiplier]
            out.append({
                "multiplier": multiplier, "scale": picked[0]["scale"], "method": method,
                "n": len(picked),
                "median_source_points": float(np.median([r["source_points"] for r in picked])),
                "median_target_points": float(np.median([r["target_points"] for r in picked])),
                "median_s": float(np.median([r["seconds"] for r in picked])),
                "median_ratio_to_1x": float(np.median(ratios[multiplier])),
                "max_ratio_to_1x": float(np.max(ratios[multiplier])),
                "success": float(np.mean([r["success"] for r in picked])),
                **stage_columns(rows, method, multiplier),
            })
    return out


def markdown(summary: list[dict]) -> str:
    """The summary as two Markdown tables: both methods, then spectral's stages (median
    seconds per multiplier; at the last, the median over the models of the seconds added
    since the first multiplier and of the ratio to it)."""
    lines = ["| points | method | n | median points (source / target) | median s "
             "| median ratio to 1x | max ratio to 1x | success |", "|" + " --- |" * 8]
    for s in summary:
        lines.append(
            f"| {s['multiplier']}x | {LABELS[s['method']]} | {s['n']} "
            f"| {s['median_source_points']:.0f} / {s['median_target_points']:.0f} "
            f"| {s['median_s']:.3f} | {s['median_ratio_to_1x']:.2f} "
            f"| {s['max_ratio_to_1x']:.2f} | {100 * s['success']:.0f}% |")
    lines += ["", "| points | " + " | ".join(f"{stage} s" for stage in GLOBAL_STAGES) + " |",
              "|" + " --- |" * (len(GLOBAL_STAGES) + 1)]
    spectral = [s for s in summary if s["method"] == SPECTRAL]
    for s in spectral:
        cells = " | ".join(f"{s[f'{stage}_median_s']:.3f}" for stage in GLOBAL_STAGES)
        lines.append(f"| {s['multiplier']}x | {cells} |")
    last = spectral[-1]
    for key, label, digits in (("added_s", "s added", 3), ("ratio_to_1x", "ratio", 2)):
        cells = " | ".join("-" if np.isnan(v := last[f"{stage}_median_{key}"]) else
                           f"{v:.{digits}f}" for stage in GLOBAL_STAGES)
        lines.append(f"| {last['multiplier']}x vs 1x, median {label} | {cells} |")
    return "\n".join(lines)


def figure(summary: list[dict], path: Path) -> None:
    """Median seconds against the points multiplier (log-x), one line per method, each
    point annotated with its median ratio to 1x; written to ``path`` (PNG)."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(5.5, 4))
    for method in METHODS:
        picked = [s for s in summary if s["method"] == method]
        x = [s["multiplier"] for s in picked]
        y = [s["median_s"] for s in picked]
        ax.plot(x, y, "o-", label=LABELS[method])
        for s in picked:
            ax.annotate(f"{s['median_ratio_to_1x']:.2f}x", (s["multiplier"], s["median_s"]),
                        textcoords="offset points", xytext=(5, 5), fontsize=8)
    multipliers = sorted({s["multiplier"] for s in summary})
    ax.set_xscale("log")
    ax.set_xticks(multipliers, [f"{m}x" for m in multipliers])
    ax.minorticks_off()
    ax.margins(x=0.15)
    ax.set_ylim(bottom=0, top=1.15 * max(s["median_s"] for s in summary))
    ax.text(0.02, 0.02, "labels: median over the models of each one's time / its time at "
            f"{multipliers[0]}x", transform=ax.transAxes, fontsize=7, color="0.3")
    ax.set_xlabel("raw points on the same surfaces (fixed voxel)")
    ax.set_ylabel("median seconds per call (one thread)")
    ax.set_title("Time against raw density, turntable pairs")
    ax.legend(fontsize=8)
    write_figure(fig, path)
    plt.close(fig)


def progress(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def parse_args() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("out/bench_density"))
    parser.add_argument("--limit", type=int, default=len(model_names()),
                        help="the first this many bundled models")
    parser.add_argument("--scales", type=int, nargs="+", default=[1, 2, 4],
                        help="linear image scales k (k^2 times the points), the first the base")
    parser.add_argument("--repeats", type=int, default=3,
                        help="timed calls per instance and method, in turn; the median is kept")
    parser.add_argument("--angle", type=float, default=45.0, help="turntable angle, degrees")
    parser.add_argument("--elevation", type=float, default=20.0,
                        help="camera elevation, degrees")
    parser.add_argument("--voxel", type=float, default=speed.SUITE_VOXEL, help="metres")
    args = parser.parse_args()
    if args.repeats < 1 or args.limit < 1 or min(args.scales) < 1:
        parser.error("--repeats, --limit and --scales must be at least 1")
    return args


def main() -> None:
    args = parse_args()
    rows: list[dict] = []
    warmed = False
    for index, model in enumerate(model_names()[:args.limit]):
        cases = [make_case(index, model, k, args.angle, args.elevation, args.voxel)
                 for k in args.scales]
        if len({c.azimuth_deg for c in cases}) > 1:
            progress(f"warning: {model}'s azimuth differs between scales (a view redrawn)")
        if not warmed:  # untimed: FFT plans, caches, compiled kernels
            for method in METHODS:
                CALLS[method](cases[0].task)
            warmed = True
        for case in cases:
            rows += run_case(case, args.repeats)
            cells = ", ".join(f"{r['method']} {r['seconds']:.3f} s "
                              f"{'ok' if r['success'] else 'FAILED'}" for r in rows[-2:])
            progress(f"{model} {case.multiplier}x ({rows[-1]['target_points']} target "
                     f"points): {cells}")

    summary = summarise(rows)
    table = markdown(summary)
    args.out.mkdir(parents=True, exist_ok=True)
    write_rows(args.out / "density.csv", rows)
    write_rows(args.out / "summary.csv", summary)
    (args.out / "summary.md").write_text(table + "\n")
    figure(summary, args.out / "density.png")
    print(table)
    progress(f"wrote {args.out / 'density.csv'}, summary.csv, summary.md, density.png")


if __name__ == "__main__":
    main()
