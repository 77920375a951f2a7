"""Experiment: the global search with its law climbs replaced by ICP verification (issue 17).

Asks whether the global spectral call could reach FPFH-RANSAC's time by checking its
placed hypotheses the way RANSAC pipelines check theirs. The variant keeps the search's
candidates, placements and focus (``search.ranked_hypotheses``), then, instead of the
law's climbs and the peak ascent, runs Open3D's point-to-plane ICP (``--distance``
voxels, ``--iterations``) from each of the ``--count`` best placed hypotheses, on the
moving cloud's one point per voxel (its part facing the target's sensor when the target
is a single view), and keeps the pose with the highest fitness at one voxel (lowest RMSE
among equals); the default polish and scoring follow (``registration._finish``). The
default call runs on the same instances in the same process, one thread, alternately.

Prints, per group, each call's successes and median / p90 time, how often the best
placed hypothesis (before any climb) and any of them lies within
:data:`PLACED_ANGLE` of the truth (symmetry-aware, scored outside the timing), and the
instances one call registers and the other does not; writes ``instances.csv`` to
``--out``.

Usage: python eval/try_icp_verification.py --suites out/suites --out out/icp_verification
       [--groups partial occluded dragon_24] [--limit 48] [--count 16]
"""

from __future__ import annotations

# isort: off
import bench_speed as speed  # first: it sets one thread before numpy and Open3D load
# isort: on

import argparse
import time
from pathlib import Path

import numpy as np
import open3d as o3d
import pandas as pd
from tqdm import tqdm

from o3d_spectral import centring, registration
from o3d_spectral.cloud import to_legacy
from o3d_spectral.law import Climb
from o3d_spectral.options import GlobalSearchOption
from o3d_spectral.refinement import near_pose
from o3d_spectral.result import SpectralRegistrationResult
from o3d_spectral.search import ranked_hypotheses

#: A placed hypothesis this close to the truth (degrees) counts as found.
PLACED_ANGLE = 10.0


def icp_verified(
    task: speed.Task, count: int, distance: float, iterations: int
) -> tuple[np.ndarray, list[np.ndarray]]:
    """The global call with ICP verification of its ``count`` best placed hypotheses in
    place of the law's climbs and the peak ascent: the 4x4 source-to-target transform, and
    every placed hypothesis as one (best placed first, in the caller's frame)."""
    voxel = task.voxel
    run = registration._start(task.source, task.target, voxel, np.eye(4), None, None, None)
    stepper, moving = run.stepper, run.moving
    ranked, _ = ranked_hypotheses(stepper, moving, GlobalSearchOption())
    fixed = registration._with_normals(to_legacy(run.target), stepper)
    criteria = o3d.pipelines.registration.ICPConvergenceCriteria(max_iteration=iterations)
    plane = o3d.pipelines.registration.TransformationEstimationPointToPlane()
    scored = []
    for h in ranked[:count]:
        start = h.transformation(moving.centroid)
        _, facing, _ = stepper.visible(moving, h.rotation, h.centre - moving.centroid)
        points = moving.points if facing is None else moving.points[facing]
        source = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
        near, _ = near_pose(fixed, points, start, (3.0 + distance) * voxel)
        if len(near.points) < 3:
            continue
        pose = np.asarray(o3d.pipelines.registration.registration_icp(
            source, near, distance * voxel, start, plane, criteria).transformation)
        fit = o3d.pipelines.registration.evaluate_registration(source, near, voxel, pose)
        scored.append((fit.fitness, -fit.inlier_rmse, pose))
    best = max(scored, key=lambda s: s[:2])[2] if scored else ranked[0].transformation(
        moving.centroid)
    result = registration._finish(run, SpectralRegistrationResult(), Climb(moving.centroid),
                                  best, registration.DEFAULT_REFINEMENT, None)
    placed = [h.transformation(moving.centroid) for h in ranked]
    if run.offset is not None:  # back to the caller's frame, as _finish does
        placed = [centring.shifted(M, -run.offset) for M in placed]
    return np.asarray(result.transformation), placed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--suites", type=Path, help="folder of the four suites")
    parser.add_argument("--out", type=Path, default=Path("out/icp_verification"))
    parser.add_argument("--groups", nargs="+", default=["partial", "occluded", "dragon_24"],
                        choices=speed.CONDITIONS + speed.real.GROUPS)
    parser.add_argument("--limit", type=int, default=48, help="instances per group")
    parser.add_argument("--rotations", type=int, default=2, help="random rotations per real case")
    parser.add_argument("--count", type=int, default=16, help="hypotheses verified")
    parser.add_argument("--distance", type=float, default=2.0, help="ICP distance, voxels")
    parser.add_argument("--iterations", type=int, default=15, help="ICP iterations")
    args = parser.parse_args()
    tasks: list[speed.Task] = []
    for group in args.groups:
        if group in speed.CONDITIONS:
            tasks += speed.suite_tasks(args.suites, group, args.limit)
        else:
            tasks += speed.real_tasks(group, args.rotations, args.limit)
    calls = {
        "law climbs (default)": lambda t: (speed.spectral_global(t), []),
        "ICP verification": lambda t: icp_verified(t, args.count, args.distance, args.iterations),
    }
    for call in calls.values():  # warm-up, untimed
        call(tasks[0])
    rows = []
    for task in tqdm(tasks, desc="icp_verification", unit="inst"):
        for name, call in calls.items():
            start = time.perf_counter()
            transformation, placed = call(task)
            seconds = time.perf_counter() - start
            rotation, translation, success = task.score(transformation)
            found = [task.score(M)[0] < PLACED_ANGLE for M in placed]
            rows.append({"group": task.group, "instance": task.name, "call": name,
                         "seconds": seconds, "rotation_error_deg": rotation,
                         "translation_error_m": translation, "success": bool(success),
                         "first_placed_found": float(found[0]) if found else np.nan,
                         "any_placed_found": float(any(found)) if found else np.nan})
    frame = pd.DataFrame(rows)
    args.out.mkdir(parents=True, exist_ok=True)
    frame.to_csv(args.out / "instances.csv", index=False)
    print(frame.groupby(["group", "call"], sort=False).agg(
        n=("success", "size"), successes=("success", "sum"), median_s=("seconds", "median"),
        p90_s=("seconds", lambda s: np.percentile(s, 90)),
        first_placed_found=("first_placed_found", "mean"),
        any_placed_found=("any_placed_found", "mean")).round(3).to_string())
    ok = frame.pivot(index="instance", columns="call", values="success")
    default, variant = list(calls)
    print("registered by the default only:", list(ok.index[ok[default] & ~ok[variant]]))
    print("registered by the variant only:", list(ok.index[~ok[default] & ok[variant]]))


if __name__ == "__main__":
    main()
