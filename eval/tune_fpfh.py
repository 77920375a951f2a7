"""Choose FPFH-RANSAC's feature and normal radii on the tuning split, for ``fpfh_ransac_tuned``.

Runs the tutorial's FPFH-RANSAC and refinement (``o3d_spectral.harness.peers``) with each
pair of the grid ``FPFH_TUNING_GRID`` (feature radius {1.5, 2, 2.5, 3.5, 5} and normal
radius {1, 1.5, 2} voxels) on the instances of the tuning split only (index % 4 == 0 of
each suite; ``fpfh_ransac_tuned`` is then run and reported on the others), one thread per
worker, each
registration seeded as the runner seeds ``fpfh_ransac_tuned``. Prints the success rate per
suite and overall for each pair, and the best pair (most successes, then the lower median
time). Copy it into ``TUNED_FPFH`` in o3d_spectral/harness/peers.py.

    python eval/tune_fpfh.py --suites suites/full suites/partial suites/occluded \\
        suites/cluttered --workers 2
    python eval/tune_fpfh.py --suites out/tiny/full --per-suite 2   # a smoke test
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one thread per registration, as the runner

import argparse  # noqa: E402
import itertools  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402
from multiprocessing import get_context  # noqa: E402

from o3d_spectral.harness.metrics import instance_metrics  # noqa: E402
from o3d_spectral.harness.peers import FPFH_TUNING_GRID, TUNED_FPFH, fpfh_ransac_with  # noqa: E402
from o3d_spectral.harness.runner import task_seed  # noqa: E402
from o3d_spectral.harness.selection import in_tuning_split  # noqa: E402
from o3d_spectral.synthetic.suite import load_suite  # noqa: E402

METHOD = "fpfh_ransac_tuned"  # the seeds are this method's


def _one(job: tuple) -> tuple:
    """Register one tuning instance with one grid pair: (pair, suite, success, seconds)."""
    import open3d as o3d

    o3d.utility.set_max_threads(1)
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    folder, index, pair, voxel_size, seed = job
    suite = load_suite(folder)
    instance = suite[index]
    features = TUNED_FPFH | {"feature_radius_voxels": pair[0], "normal_radius_voxels": pair[1]}
    condition = suite.manifest["instances"][index]["condition"]
    method_seed = task_seed(seed, condition, suite.manifest["seed"], index, METHOD)
    start = time.perf_counter()
    transformation, _ = fpfh_ransac_with(features)(
        instance.source, instance.target, voxel_size, method_seed
    )
    seconds = time.perf_counter() - start
    return pair, suite.root.name, instance_metrics(transformation, instance)["success"], seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--suites", nargs="+", required=True, help="suite folders")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--voxel-size", type=float, default=0.008)
    parser.add_argument("--seed", type=int, default=0, help="run seed (default 0)")
    parser.add_argument("--per-suite", type=int, help="only the first N tuning instances")
    args = parser.parse_args()
    grid = list(itertools.product(*FPFH_TUNING_GRID.values()))
    jobs = []
    for folder in args.suites:
        indices = [i for i in range(len(load_suite(folder))) if in_tuning_split(i)]
        for index in indices[: args.per_suite]:
            jobs += [(folder, index, pair, args.voxel_size, args.seed) for pair in grid]
    with ProcessPoolExecutor(args.workers, mp_context=get_context("spawn")) as pool:
        results = list(pool.map(_one, jobs))
    suites = list(dict.fromkeys(suite for _, suite, _, _ in results))
    print("feature_r normal_r  " + "  ".join(f"{s:>10}" for s in suites) + "     all  time_s")
    scores = {}
    for pair in grid:
        mine = [r for r in results if r[0] == pair]
        rates = [statistics.mean(r[2] for r in mine if r[1] == s) for s in suites]
        overall = statistics.mean(r[2] for r in mine)
        seconds = statistics.median(r[3] for r in mine)
        scores[pair] = (overall, -seconds)
        cells = "  ".join(f"{100 * rate:9.1f}%" for rate in rates)
        print(f"{pair[0]:9g} {pair[1]:8g}  {cells}  {100 * overall:5.1f}%  {seconds:6.3f}")
    best = max(grid, key=scores.get)
    print(f"best on {len(results) // len(grid)} tuning instances: feature_radius_voxels="
          f"{best[0]:g}, normal_radius_voxels={best[1]:g}")


if __name__ == "__main__":
    main()
