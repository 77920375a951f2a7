"""Benchmark: the global spectral call against FPFH-RANSAC, time and success.

The methods run on the same instances in the same run, one thread each (``--all-cores``:
at their defaults on every core). Each instance is timed ``--repeats`` times, the
methods in turn (A B C A B C ...: a drift of the machine's speed falls on all), with
``time.perf_counter`` around the call only (loading, rotating and scoring are outside),
and its median time is kept; the first call's pose is scored. One untimed call of each
method on the first instance warms up FFT plans and caches first.

* spectral: ``o3d_spectral.registration_spectral_global(source, target, voxel)``, defaults
  (on one thread: ``GlobalSearchOption(workers=1)``).
* lean FPFH-RANSAC, the reference of every ratio: the harness's ``fpfh_ransac_lean``
  (Open3D's tutorial features and RANSAC, its point-to-plane ICP on both clouds thinned to
  half the voxel, the thinned target's normals estimated there): FPFH-RANSAC as users tune
  it for speed.
* tutorial FPFH-RANSAC: the harness's ``fpfh_ransac`` (the same, with its ICP on the full
  clouds, seeded as the harness seeds it). Its ICP needs target normals: when the target
  has none (the real cases), the method estimates them *inside the timed call*
  (``harness.tutorial.with_target_normals``: radius 2 voxels, 30 neighbours, on a copy), so
  every method starts from the same normal-free input.

Groups and voxel sizes:

* suites (``--suites DIR`` holding ``full``, ``partial``, ``occluded``, ``cluttered``, made by
  ``o3d-spectral make-suite COND --n 48 --seed 0 --out DIR/COND``): the first 48 instances
  of each, 8 mm; success symmetry-aware, 5 deg and 1 cm at the source centroid
  (``harness.metrics.instance_metrics``).
* ``crop_in_scene``: the object's points cut out of each of the first 48 cluttered views
  by its label, at a seeded random pose, against the whole view (as a user crops an
  object out of a depth image and registers it to the frame); success: plain errors
  under 5 degrees and 1 cm at the crop's centroid.
* ``wide``: one view of each of the 12 bundled models (cut out by its label) against a
  reconstructed tabletop 2 m wide holding 8 objects per square metre
  (``o3d_spectral.synthetic.wide``), 8 mm; success as the suites'.
* ``turntable_45``, ``turntable_90``, ``turntable_135``: two depth views of each bundled
  model, the turntable turned that far between them, at 20 and 45 degrees of elevation,
  each view in its own camera frame (``o3d_spectral.synthetic.turntable``), 8 mm; success
  symmetry-aware, 5 deg and 1 cm.
* ``dragon_unoriented``: the dragon pairs 24-72 degrees apart with both clouds' normals as
  Open3D's ``estimate_normals()`` leaves them, unoriented (``real.with_normals``).
* ``dragon_model``: the dragon model into each of its eight scans, the model the other
  seven scans merged at their recorded poses (thinned to 1 mm), turned by ``--rotations``
  seeded random rotations; 5 mm.
* ``room_fragments``: the pairs of a synthetic room's fragments that overlap by over 30%
  (``o3d_spectral.synthetic.room``, seed 300: a furnished room 4.6 x 3.8 m fused in runs of
  five depth frames, 1 cm points, no normals, each fragment in its first camera's frame),
  5 cm, as the geometric-registration benchmark's fragments are registered; success: its
  recall's rotation error under 15 degrees and translation error under 30 cm.
* real cases (``o3d_spectral.harness.real``; ``dragon_24`` to ``dragon_120``: 5 mm, the
  dragon is 0.2 m across; ``ycbv_crop``, ``ycbv_frame``: 8 mm, as the suites' YCB
  objects): every case from ``--rotations`` seeded random rotations of its source (uniform
  over SO(3) about its centroid); success: symmetry-aware rotation error < 5 deg and
  translation error at the source centroid < 1 cm (``real.case_errors``).

Reports per group: n, median and p90 time of each method (over the instances), the ratios
spectral / lean FPFH-RANSAC of the medians and of the p90s (and spectral / tutorial of the
medians), each method's success rate, and the share
of spectral calls that stopped early (``result.confirmed``) with the number of those that
failed. Prints a
Markdown table and writes ``instances.csv``, ``summary.csv`` and ``summary.md`` to ``--out``.

Usage: python eval/bench_speed.py --suites out/suites --out out/bench_speed
       [--rotations 5] [--groups full dragon_24 ...] [--limit 3] [--repeats 3] [--all-cores]
"""

from __future__ import annotations

import os
import sys

ONE_THREAD = "--all-cores" not in sys.argv
if ONE_THREAD:
    for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                 "NUMEXPR_NUM_THREADS", "NUMBA_NUM_THREADS"):
        os.environ.setdefault(_var, "1")  # one thread for both methods

import argparse  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402
from collections.abc import Iterator  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import open3d as o3d  # noqa: E402
from tqdm import tqdm  # noqa: E402

import o3d_spectral  # noqa: E402
from o3d_spectral.harness import real  # noqa: E402
from o3d_spectral.harness.errors import rotation_error, translation_error  # noqa: E402
from o3d_spectral.harness.methods import get_method  # noqa: E402
from o3d_spectral.harness.metrics import instance_score  # noqa: E402
from o3d_spectral.harness.pairs import RECALL_ROTATION_DEG, RECALL_TRANSLATION_M  # noqa: E402
from o3d_spectral.harness.runner import task_seed  # noqa: E402
from o3d_spectral.harness.writers import write_rows  # noqa: E402
from o3d_spectral.synthetic.models import model_names  # noqa: E402
from o3d_spectral.synthetic.room import RoomOptions, fragment_pairs, room_fragments  # noqa: E402
from o3d_spectral.synthetic.sampling import rigid, sample_rotation  # noqa: E402
from o3d_spectral.synthetic.suite import load_suite  # noqa: E402
from o3d_spectral.synthetic.turntable import TURNTABLE_ELEVATIONS, turntable_pair  # noqa: E402
from o3d_spectral.synthetic.wide import wide_scene_instance  # noqa: E402

if ONE_THREAD:
    o3d.utility.set_max_threads(1)  # Open3D's TBB pool has no environment variable

CONDITIONS = ("full", "partial", "occluded", "cluttered")
SUITE_VOXEL = 0.008
METHODS = ("spectral_global", "fpfh_ransac_lean", "fpfh_ransac")
#: The method every ratio divides by.
REFERENCE = "fpfh_ransac_lean"
SUITE_SIZE = 48
#: Width (metres) of the tabletop of the ``wide`` group.
WIDE_WIDTH = 2.0


@dataclass
class Task:
    """One timed problem: clouds, voxel, seed, and how to score an estimate."""

    group: str
    name: str
    source: o3d.geometry.PointCloud
    target: o3d.geometry.PointCloud
    voxel: float
    seed: int
    score: object  # (T) -> (rotation_error_deg, translation_error_m, success)


def spectral_global(task: Task) -> tuple[np.ndarray, dict]:
    search = o3d_spectral.GlobalSearchOption(workers=1) if ONE_THREAD else None  # or default
    result = o3d_spectral.registration_spectral_global(task.source, task.target, task.voxel,
                                                       search=search)
    warned = any("may be wrong" in w for w in result.warnings)
    return np.asarray(result.transformation), {
        "confirmed": result.confirmed, "fitness": result.fitness, "fit": result.fit,
        "confidence": result.confidence, "may_be_wrong_warning": warned}


def harness_call(name: str):
    """The harness method ``name`` as a call of a task (its seed), with the spectral
    call's extra columns empty."""
    def call(task: Task) -> tuple[np.ndarray, dict]:
        transformation, _ = get_method(name)(task.source, task.target, task.voxel, task.seed)
        return transformation, {"confirmed": False, "fitness": float("nan"),
                                "fit": float("nan"), "confidence": float("nan"),
                                "may_be_wrong_warning": False}
    return call


CALLS = {"spectral_global": spectral_global, **{m: harness_call(m) for m in METHODS[1:]}}
#: The turntable groups and their angles (degrees).
TURNTABLE_GROUPS = {"turntable_45": 45, "turntable_90": 90, "turntable_135": 135}
#: The dragon pairs registered with unoriented normals.
UNORIENTED_GROUPS = ("dragon_24", "dragon_48", "dragon_72")
#: Spacing (metres) the merged dragon model is thinned to.
DRAGON_MODEL_SPACING = 0.001
#: The synthetic room of the ``room_fragments`` group, and the voxel (metres) its
#: fragments are registered at (the geometric-registration benchmark's).
ROOM_SEED, ROOM_VOXEL = 300, 0.05
ALL_GROUPS = (*CONDITIONS, "crop_in_scene", "wide", *TURNTABLE_GROUPS, "dragon_unoriented",
              "dragon_model", "room_fragments", *real.GROUPS)


#: The groups made from the suites' folder (``--suites``).
SUITE_GROUPS = (*CONDITIONS, "crop_in_scene")


def group_tasks(group: str, suites: Path | None, rotations: int, limit: int) -> list[Task]:
    """The instances of ``group`` (one of :data:`ALL_GROUPS`), at most ``limit``."""
    if group in CONDITIONS:
        return list(suite_tasks(suites, group, limit))
    if group == "crop_in_scene":
        return list(crop_tasks(suites, limit))
    if group == "wide":
        return list(wide_tasks(limit))
    if group in TURNTABLE_GROUPS:
        return list(turntable_tasks(group, limit))
    if group == "dragon_unoriented":
        return list(unoriented_tasks(rotations, limit))
    if group == "dragon_model":
        return list(dragon_model_tasks(rotations, limit))
    if group == "room_fragments":
        return list(room_tasks(limit))
    return list(real_tasks(group, rotations, limit))


def suite_tasks(root: Path, condition: str, limit: int) -> Iterator[Task]:
    suite = load_suite(root / condition)
    for index in range(min(SUITE_SIZE, limit, len(suite))):
        instance = suite[index]
        seed = task_seed(0, condition, int(suite.manifest["seed"]), index, "fpfh_ransac")
        yield Task(condition, f"{condition}_{index:03d}", instance.source, instance.target,
                   SUITE_VOXEL, seed, instance_score(instance))


def wide_tasks(limit: int) -> Iterator[Task]:
    """One view of each bundled model against a reconstructed tabletop :data:`WIDE_WIDTH`
    metres wide (:func:`o3d_spectral.synthetic.wide.wide_scene_instance`, seed 100 + i)."""
    for index, name in enumerate(model_names()[:limit]):
        instance = wide_scene_instance(name, WIDE_WIDTH, np.random.default_rng(100 + index))
        yield Task("wide", f"wide_{name}", instance.source, instance.target, SUITE_VOXEL,
                   index, instance_score(instance))


def turntable_tasks(group: str, limit: int) -> Iterator[Task]:
    """Two depth views of each bundled model :data:`TURNTABLE_GROUPS` degrees apart, at
    each of :data:`~o3d_spectral.synthetic.turntable.TURNTABLE_ELEVATIONS` (seed 200 + i)."""
    pairs = [(name, elevation) for elevation in TURNTABLE_ELEVATIONS for name in model_names()]
    for index, (name, elevation) in enumerate(pairs[:limit]):
        pair = turntable_pair(name, TURNTABLE_GROUPS[group], elevation,
                              np.random.default_rng(200 + index))
        yield Task(group, f"{group}_{name}_{elevation}", pair.source, pair.target, SUITE_VOXEL,
                   index, instance_score(pair))


def unoriented_tasks(rotations: int, limit: int) -> Iterator[Task]:
    """The dragon pairs of :data:`UNORIENTED_GROUPS`, turned as :func:`real_tasks` turns
    them, both clouds with Open3D's unoriented normals (``real.with_normals``)."""
    turned = real.rotated_cases(list(UNORIENTED_GROUPS), rotations)
    for count, (case, motion, seed, r) in enumerate(turned):
        if count >= limit:
            return
        case = real.with_normals(case, "unoriented", motion)
        yield Task("dragon_unoriented", f"{case.name}_r{r}_unoriented", case.source,
                   case.target, real.VOXEL_SIZES[case.group], seed, real.case_score(case))


def dragon_model_tasks(rotations: int, limit: int) -> Iterator[Task]:
    """The dragon model (the seven other scans merged in the world frame of
    ``real.dragon_pose``, thinned to :data:`DRAGON_MODEL_SPACING`) into each scan, in the
    scan's frame, from ``rotations`` seeded random rotations of the model."""
    folder = real.real_dir() / "dragon"
    scans = {a: o3d.io.read_point_cloud(str(folder / f"dragonStandRight_{a}.ply"))
             for a in real.DRAGON_ANGLES}
    count = 0
    for angle in real.DRAGON_ANGLES:
        model = o3d.geometry.PointCloud()
        for other in real.DRAGON_ANGLES:
            if other != angle:
                model += o3d.geometry.PointCloud(scans[other]).transform(real.dragon_pose(other))
        model = model.voxel_down_sample(DRAGON_MODEL_SPACING)
        case = real.RealCase(f"dragon_model_{angle}", "dragon_model", model,
                             o3d.geometry.PointCloud(scans[angle]),
                             np.linalg.inv(real.dragon_pose(angle)))
        for r in range(rotations):
            if count >= limit:
                return
            seed = real.rotation_seed(case.name, r)
            turned, _ = real.randomly_rotated(case, seed)
            yield Task("dragon_model", f"{case.name}_r{r}", turned.source, turned.target,
                       real.DRAGON_VOXEL, seed, real.case_score(turned))
            count += 1


def room_tasks(limit: int) -> Iterator[Task]:
    """The fragment pairs of the room :data:`ROOM_SEED` overlapping by over 30%
    (:func:`o3d_spectral.synthetic.room.fragment_pairs`), fragment ``j`` onto fragment
    ``i``, in their order in ``gt.log``."""
    fragments = room_fragments(RoomOptions(), ROOM_SEED)
    for index, ((i, j), truth) in enumerate(sorted(fragment_pairs(fragments).items())[:limit]):
        source, target = (o3d.geometry.PointCloud(o3d.utility.Vector3dVector(fragments[k].points))
                          for k in (j, i))

        def score(T, truth=truth):
            rot, tra = rotation_error(T, truth), translation_error(T, truth)
            return rot, tra, bool(rot < RECALL_ROTATION_DEG and tra < RECALL_TRANSLATION_M)

        yield Task("room_fragments", f"room_{ROOM_SEED}_{i}_{j}", source, target, ROOM_VOXEL,
                   index, score)


def crop_tasks(root: Path, limit: int) -> Iterator[Task]:
    """The object's own points cut out of each cluttered scene view (by its label, as a
    user crops a depth image), presented at a seeded random pose, against the whole view:
    a view of one object in a view of a scene."""
    suite = load_suite(root / "cluttered")
    for index in range(min(SUITE_SIZE, limit, len(suite))):
        instance = suite[index]
        points = np.asarray(instance.target.points)[instance.target_labels == 0]
        rng = np.random.default_rng(index)
        presentation = rigid(sample_rotation(rng), rng.uniform(-0.1, 0.1, size=3))
        source = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
        source.transform(presentation)
        truth, centre = np.linalg.inv(presentation), np.asarray(source.points).mean(axis=0)

        def score(T, truth=truth, centre=centre):
            rot, tra = rotation_error(T, truth), translation_error(T, truth, center=centre)
            return rot, tra, bool(rot < 5.0 and tra < 0.01)

        yield Task("crop_in_scene", f"crop_in_scene_{index:03d}", source, instance.target,
                   SUITE_VOXEL, index, score)


def real_tasks(group: str, rotations: int, limit: int) -> Iterator[Task]:
    for count, (turned, _, seed, r) in enumerate(real.rotated_cases([group], rotations)):
        if count >= limit:
            return
        yield Task(group, f"{turned.name}_r{r}", turned.source, turned.target,
                   real.VOXEL_SIZES[group], seed, real.case_score(turned))


def run_task(task: Task, repeats: int) -> list[dict]:
    """One row per method: the median of ``repeats`` timed calls (the methods in turn)
    and the score of the first call's pose."""
    seconds: dict[str, list[float]] = {method: [] for method in METHODS}
    first: dict[str, tuple[np.ndarray, dict]] = {}
    for _ in range(repeats):
        for method in METHODS:
            start = time.perf_counter()
            outcome = CALLS[method](task)
            seconds[method].append(time.perf_counter() - start)
            first.setdefault(method, outcome)
    rows = []
    for method in METHODS:
        T, extra = first[method]
        rot, tra, success = task.score(T)
        rows.append({
            "group": task.group, "instance": task.name, "method": method,
            "voxel_m": task.voxel, "source_points": len(task.source.points),
            "target_points": len(task.target.points),
            "seconds": float(np.median(seconds[method])),
            "rotation_error_deg": rot, "translation_error_m": tra, "success": bool(success),
            **extra,
        })
    return rows


def add_task_arguments(parser: argparse.ArgumentParser, *, limit: int, rotations: int) -> None:
    """The options that choose the bench's instances (``--suites``, ``--groups``,
    ``--limit``, ``--rotations``), with the script's defaults for the last two."""
    parser.add_argument("--suites", type=Path, help="folder of the four suites (skipped if absent)")
    parser.add_argument("--groups", nargs="+", choices=ALL_GROUPS, default=list(ALL_GROUPS))
    parser.add_argument("--limit", type=int, default=limit,
                        help="at most this many instances per group (a quick run)")
    parser.add_argument("--rotations", type=int, default=rotations,
                        help="random rotations per real case")


def chosen_groups(args: argparse.Namespace) -> list[str]:
    """The groups of ``args.groups`` in the bench's order, the suites' only with
    ``args.suites``."""
    return [g for g in ALL_GROUPS
            if g in args.groups and (args.suites is not None or g not in SUITE_GROUPS)]


def chosen_tasks(parser: argparse.ArgumentParser, args: argparse.Namespace,
                 groups: list[str]) -> list[Task]:
    """The instances of ``groups`` as ``args`` chooses them; a parser error where there
    are none."""
    tasks = [t for g in groups for t in group_tasks(g, args.suites, args.rotations, args.limit)]
    if not tasks:
        parser.error("no instances: give --suites or real groups")
    return tasks


def summarise(rows: list[dict], groups: list[str]) -> list[dict]:
    out = []
    for group in groups:
        picked = {m: [r for r in rows if r["group"] == group and r["method"] == m]
                  for m in METHODS}
        if not picked[METHODS[0]]:
            continue
        line = {"group": group, "n": len(picked[METHODS[0]])}
        for m in METHODS:
            t = np.array([r["seconds"] for r in picked[m]])
            line[f"{m}_median_s"] = float(np.median(t))
            line[f"{m}_p90_s"] = float(np.percentile(t, 90))
            line[f"{m}_success"] = float(np.mean([r["success"] for r in picked[m]]))
        confirmed = [r for r in picked[METHODS[0]] if r["confirmed"]]
        line["early_stops"] = len(confirmed) / line["n"]
        line["early_stops_wrong"] = sum(not r["success"] for r in confirmed)
        a = METHODS[0]
        line["ratio_median"] = line[f"{a}_median_s"] / line[f"{REFERENCE}_median_s"]
        line["ratio_p90"] = line[f"{a}_p90_s"] / line[f"{REFERENCE}_p90_s"]
        line["ratio_median_tutorial"] = line[f"{a}_median_s"] / line["fpfh_ransac_median_s"]
        out.append(line)
    return out


def markdown(summary: list[dict]) -> str:
    head = ("| group | n | spectral median s | lean FPFH median s | tutorial FPFH median s "
            "| ratio median | ratio p90 | ratio median (tutorial) | spectral success "
            "| lean FPFH success | tutorial FPFH success | early stops | wrong early stops |")
    lines = [head, "|" + " --- |" * 13]
    for s in summary:
        lines.append(
            f"| {s['group']} | {s['n']} | {s['spectral_global_median_s']:.3f} "
            f"| {s['fpfh_ransac_lean_median_s']:.3f} | {s['fpfh_ransac_median_s']:.3f} "
            f"| {s['ratio_median']:.2f} | {s['ratio_p90']:.2f} "
            f"| {s['ratio_median_tutorial']:.2f} "
            f"| {100 * s['spectral_global_success']:.0f}% "
            f"| {100 * s['fpfh_ransac_lean_success']:.0f}% "
            f"| {100 * s['fpfh_ransac_success']:.0f}% "
            f"| {100 * s['early_stops']:.0f}% | {s['early_stops_wrong']} |"
        )
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_task_arguments(parser, limit=10**9, rotations=5)
    parser.add_argument("--out", type=Path, default=Path("out/bench_speed"))
    parser.add_argument("--all-cores", action="store_true",
                        help="both methods at their defaults on every core (default: one thread)")
    parser.add_argument("--repeats", type=int, default=3,
                        help="timed calls per instance and method, in turn; the median is kept")
    args = parser.parse_args()
    if args.repeats < 1:
        parser.error(f"--repeats must be at least 1, got {args.repeats}")
    groups = chosen_groups(args)
    tasks = chosen_tasks(parser, args, groups)
    for method in METHODS:  # warm-up, untimed: FFT plans, caches, lazy imports
        CALLS[method](tasks[0])

    rows: list[dict] = []
    for task in tqdm(tasks, desc="bench_speed", unit="inst"):
        rows += run_task(task, args.repeats)

    summary = summarise(rows, groups)
    table = markdown(summary)
    args.out.mkdir(parents=True, exist_ok=True)
    write_rows(args.out / "instances.csv", rows)
    write_rows(args.out / "summary.csv", summary)
    threads = "one thread" if ONE_THREAD else f"all {os.cpu_count()} cores"
    note = (f"{platform.processor() or platform.machine()}, Open3D {o3d.__version__}, {threads} "
            f"(Open3D max threads {o3d.utility.get_max_threads()}); each instance's median of "
            f"{args.repeats} timed calls, the methods in turn; "
            "ratio = spectral / lean FPFH-RANSAC (tutorial: / the tutorial's); early stops: "
            "share of spectral calls confirmed before the climbs, and how many of those failed")
    (args.out / "summary.md").write_text(table + "\n\n" + note + "\n")
    print(table)
    print(note)
    print(f"wrote {args.out / 'instances.csv'}, summary.csv, summary.md")


if __name__ == "__main__":
    main()
