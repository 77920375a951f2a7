"""Benchmark: does the coarse ranking of the candidates keep the right rotation?

Outside a scene (two scans, or a model against a view of it), the global call places its
candidate rotations (the EGI's peaks; between two scans also the shells' peaks and the
sweep's best) on a grid of twice the voxel first and only the
``GlobalSearchOption.coarse_placements`` best at full resolution. This script measures,
for every case of ``--groups`` (the dragon pairs by default; the suites' ``full``,
``partial`` and ``occluded`` views with ``--suites``; ``ycbv_crop``), the rank of the first
candidate within ``--within`` degrees of the truth when the candidates are ranked by their
phase-correlation peak on grids of 4, 2 and 1 voxels, and prints the recall at a few
ranks per level and group kind (cases with no such candidate at all are counted apart:
no ranking can keep them).

Then, with ``--counts``, it runs the whole global call with each value of
``coarse_placements`` on the same cases and on synthetic pairs of views of the twelve
bundled models (two depth views 30-75 degrees apart, ``--view-pairs`` per model), and
prints success per group and total time per value.

Usage: python eval/bench_pyramid.py [--groups dragon_24 full ...] [--suites DIR]
       [--limit 48] [--counts 32 16 8]
"""

from __future__ import annotations

# isort: off
import bench_speed as speed  # first: it sets one thread before numpy and Open3D load
# isort: on

import argparse
import time
from collections import Counter
from pathlib import Path

import numpy as np

import o3d_spectral
from o3d_spectral import run as runs
from o3d_spectral.harness.errors import symmetric_rotation_error, symmetric_translation_error
from o3d_spectral.search.candidates import (
    egi_candidates,
    placed_peaks,
    shell_candidates,
    span_factor,
    swept_candidates,
)
from o3d_spectral.search.placement import PLACEMENT_SPAN
from o3d_spectral.spectra import so3
from o3d_spectral.synthetic.camera import look_at, scan_meshes
from o3d_spectral.synthetic.models import load_model, model_names
from o3d_spectral.synthetic.sampling import point_cloud
from o3d_spectral.synthetic.sensor import CameraIntrinsics, DepthNoise
from o3d_spectral.synthetic.symmetry import model_symmetry

DRAGONS = ("dragon_24", "dragon_48", "dragon_72", "dragon_96", "dragon_120")
#: Groups of a model against a view of it (the suites' views, RGB-D crops).
VIEWS = ("full", "partial", "occluded", "ycbv_crop")
LEVELS = (4.0, 2.0, 1.0)
RANKS = (1, 2, 4, 8, 16, 32)
VOXEL = 0.008


def first_good_rank(task: speed.Task, within: float) -> dict[float, int] | None:
    """Per grid level (voxels), the 1-based rank of the first candidate within ``within``
    degrees of the truth; None when no candidate is."""
    run = runs.start(task.source, task.target, task.voxel, np.eye(4), None, None, None)
    stepper, moving = run.stepper, run.moving
    search = o3d_spectral.GlobalSearchOption(workers=1)
    candidates = egi_candidates(stepper, moving, search)
    factor = 1.0
    if run.situation.two_scans:
        candidates += (shell_candidates(stepper.target_points, moving.points,
                                        search.shell_hypotheses)
                       + swept_candidates(stepper, moving, search.sweep_rotations))
        factor = span_factor(stepper.voxel_size, moving.radius, PLACEMENT_SPAN)
    rotations = [c.rotation for c in candidates]
    errors = np.array([task.score(so3.about_pivot(R, np.zeros(3), moving.centroid))[0]
                       for R in rotations])
    good = errors <= within
    if not good.any():
        return None
    ranks = {}
    for level in LEVELS:
        order = np.argsort(-placed_peaks(stepper, moving, rotations, factor * level),
                           kind="stable")
        ranks[level] = int(np.flatnonzero(good[order])[0]) + 1
    return ranks


def kind(group: str) -> str:
    """``"dragon pairs"`` or ``"model and view"``."""
    return "dragon pairs" if group in DRAGONS else "model and view"


def view_pairs(per_model: int, seed: int = 11) -> list[tuple]:
    """Two noisy depth views of each bundled model, 30-75 degrees apart, 0.45 m away:
    (name, source, target, scoring function)."""
    rng = np.random.default_rng(seed)
    pairs = []
    for name in model_names():
        mesh = load_model(name)
        centre = mesh.get_center()
        for k in range(per_model):
            a = rng.normal(size=3)
            a /= np.linalg.norm(a)
            side = np.cross(a, rng.normal(size=3))
            side /= np.linalg.norm(side)
            angle = np.deg2rad(rng.uniform(30.0, 75.0))
            b = np.cos(angle) * a + np.sin(angle) * side
            poses = [look_at(centre + 0.45 * d, centre,
                             up=(0, 0, 1) if abs(d[2]) < 0.9 else (1, 0, 0)) for d in (a, b)]
            scans = [scan_meshes([mesh], CameraIntrinsics(), W, noise=DepthNoise(), rng=rng)
                     for W in poses]
            clouds = [point_cloud(s.points, s.normals) for s in scans]
            pairs.append((f"{name}_{k}", *clouds, _view_score(*poses, name, centre)))
    return pairs


def _view_score(source_pose, target_pose, name, centre):
    symmetry = model_symmetry(name)

    def score(T):
        estimate, truth = T @ np.linalg.inv(source_pose), np.linalg.inv(target_pose)
        rotation = symmetric_rotation_error(estimate, truth, symmetry)
        shift = symmetric_translation_error(estimate, truth, symmetry, center=centre)
        return rotation, shift, rotation <= 10.0 and shift <= 0.02

    return score


def tasks(groups: list[str], suites: Path | None, rotations: int, limit: int) -> list:
    """The cases of ``groups`` (:func:`bench_speed.group_tasks`)."""
    return [t for group in groups for t in speed.group_tasks(group, suites, rotations, limit)]


def recall_table(cases: list, within: float) -> str:
    """The recall per grid level of each kind of case (:func:`kind`), Markdown."""
    lines = ["| cases | grid (voxels) | " + " | ".join(f"recall@{k}" for k in RANKS)
             + " | worst rank |", "| --- | --- |" + " --- |" * (len(RANKS) + 1)]
    for name in dict.fromkeys(kind(t.group) for t in cases):
        ranks = [first_good_rank(t, within) for t in cases if kind(t.group) == name]
        found = [r for r in ranks if r is not None]
        label = f"{name} ({len(found)} of {len(ranks)} with a candidate within {within:g} deg)"
        for level in LEVELS:
            worst = max((r[level] for r in found), default=0)
            cells = " | ".join(f"{sum(r[level] <= k for r in found)}/{len(found)}"
                               for k in RANKS)
            lines.append(f"| {label} | {level:g} | {cells} | {worst} |")
    return "\n".join(lines)


def counts_table(cases: list, counts: list[int], per_model: int) -> str:
    """Success per group (and on synthetic view pairs) and total time of the whole call
    with each ``coarse_placements``, Markdown."""
    runs_ = [(t.group, t.source, t.target, t.score, t.voxel) for t in cases]
    runs_ += [("view pairs", *pair[1:], VOXEL) for pair in view_pairs(per_model)]
    names = list(dict.fromkeys(group for group, *_ in runs_))
    sizes = Counter(group for group, *_ in runs_)
    lines = ["| coarse_placements | " + " | ".join(names) + " | total time (s) |",
             "| --- |" + " --- |" * (len(names) + 1)]
    for count in counts:
        search = o3d_spectral.GlobalSearchOption(workers=1, coarse_placements=count)
        good, total = Counter(), 0.0
        for group, source, target, score, voxel in runs_:
            start = time.perf_counter()
            result = o3d_spectral.registration_spectral_global(source, target, voxel,
                                                               search=search)
            total += time.perf_counter() - start
            good[group] += bool(score(np.asarray(result.transformation))[2])
        cells = " | ".join(f"{good[name]}/{sizes[name]}" for name in names)
        lines.append(f"| {count} | {cells} | {total:.1f} |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--groups", nargs="+", default=list(DRAGONS),
                        choices=(*DRAGONS, *VIEWS))
    parser.add_argument("--suites", type=Path, help="folder of the suites (for their groups)")
    parser.add_argument("--limit", type=int, default=48, help="cases per group at most")
    parser.add_argument("--rotations", type=int, default=2, help="random rotations per pair")
    parser.add_argument("--within", type=float, default=10.0, help="degrees")
    parser.add_argument("--counts", type=int, nargs="*", default=[],
                        help="coarse_placements values to run the whole call with")
    parser.add_argument("--view-pairs", type=int, default=2, help="view pairs per model")
    args = parser.parse_args()
    cases = tasks(args.groups, args.suites, args.rotations, args.limit)
    print(recall_table(cases, args.within), flush=True)
    if args.counts:
        print()
        print(counts_table(cases, args.counts, args.view_pairs))


if __name__ == "__main__":
    main()
