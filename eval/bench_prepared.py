"""Benchmark: one model registered to many scans, prepared once or on every call.

The model points of one bundled object (``--object``, Poisson-disk samples with outward
normals, its mesh frame) against the targets of the partial suite's instances of that
object (20 single views in a 240-instance suite), 8 mm, one thread: the global call on
each scan with the model cloud itself, and with ``o3d_spectral.prepare(model, 0.008)``
made once (its time counted in the total); ``--without-normals``: the model's points
alone, as a scanned model comes, its normals estimated. Both runs alternate ``--repeats`` times; the
median totals and their ratio are printed, with the successes (5 degrees, 1 cm at the
model's centroid, symmetry-aware: ``harness.metrics``) of each, which must agree; with
``--out``, every timed run as a CSV row.

Usage: python eval/bench_prepared.py --suite out/suites/partial [--object power_drill]
       [--repeats 3] [--without-normals] [--out out/bench_prepared.csv]
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

import o3d_spectral
from o3d_spectral.harness.errors import symmetric_rotation_error, symmetric_translation_error
from o3d_spectral.harness.writers import write_rows
from o3d_spectral.synthetic.sampling import model_cloud, point_cloud
from o3d_spectral.synthetic.suite import load_suite
from o3d_spectral.synthetic.symmetry import Symmetry, model_symmetry


def scans(suite_dir: Path, name: str) -> list[tuple[object, np.ndarray]]:
    """The suite's targets of object ``name`` with the model-to-target ground truth."""
    suite = load_suite(suite_dir)
    found = []
    for index in range(len(suite)):
        instance = suite[index]
        if instance.object == name:
            found.append((instance.target, instance.T_gt @ instance.source_from_model))
    return found


def run(
    model, cases, voxel: float, prepared: bool, symmetry: Symmetry
) -> tuple[float, list[bool]]:
    """Total seconds of registering ``model`` to every case, and each one's success."""
    centre = np.asarray(model.points).mean(axis=0)
    start = time.perf_counter()
    source = o3d_spectral.prepare(model, voxel) if prepared else model
    search = o3d_spectral.GlobalSearchOption(workers=1)  # one thread, as the other benches
    poses = [o3d_spectral.registration_spectral_global(source, target, voxel,
                                                       search=search).transformation
             for target, _ in cases]
    seconds = time.perf_counter() - start
    ok = [symmetric_rotation_error(T, truth, symmetry) < 5.0
          and symmetric_translation_error(T, truth, symmetry, center=centre) < 0.01
          for T, (_, truth) in zip(poses, cases, strict=True)]
    return seconds, ok


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--suite", type=Path, required=True, help="a partial suite's folder")
    parser.add_argument("--object", default="power_drill")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--without-normals", action="store_true",
                        help="the model's points alone (its normals estimated)")
    parser.add_argument("--out", type=Path, help="write every timed run here as a CSV row")
    args = parser.parse_args()
    model = point_cloud(*(a.copy() for a in model_cloud(args.object, 20000)))
    if args.without_normals:
        model.normals = o3d.utility.Vector3dVector()
    symmetry = model_symmetry(args.object)
    cases = scans(args.suite, args.object)
    run(model, cases[:1], speed.SUITE_VOXEL, True, symmetry)  # untimed warm-up
    normals = "estimated" if args.without_normals else "given"
    totals, rows = {False: [], True: []}, []
    for repeat in range(args.repeats):
        for prepared in (False, True):
            seconds, ok = run(model, cases, speed.SUITE_VOXEL, prepared, symmetry)
            totals[prepared].append(seconds)
            rows.append({"object": args.object, "normals": normals, "scans": len(cases),
                         "repeat": repeat, "prepared": prepared, "seconds": seconds,
                         "registered": sum(ok)})
            print(f"prepared={prepared}: {seconds:.2f} s, {sum(ok)} of {len(ok)} registered",
                  flush=True)
    if args.out:
        write_rows(args.out, rows)
    plain, ready = np.median(totals[False]), np.median(totals[True])
    print(f"| model | its normals | scans | each call prepares (s) | prepared once (s) | ratio |\n"
          f"| --- | --- | --- | --- | --- | --- |\n"
          f"| {args.object} | {normals} | {len(cases)} | {plain:.2f} | {ready:.2f} "
          f"| {ready / plain:.2f} |")


if __name__ == "__main__":
    main()
