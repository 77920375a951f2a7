"""Benchmark: milliseconds per control-law iteration (paper: 8.7 ms, C++, 8 mm, B = 16).

Runs the law's per-iteration work (``SpectralStepper.evaluate`` and the update, the
translation searched about the previous prediction as ``law.climb`` does) on the mustard
bottle at 8 mm voxels and B = 16, single-threaded, and in the same run times two 3D FFTs
of the same grid (one forward, one inverse: the least any FFT-based iteration does).
Prints medians over several runs of many iterations each, and the ratios; with ``--out``,
writes them as one CSV row.

Usage: python eval/bench_iteration.py [--iterations 50] [--runs 5] [--object mustard_bottle]
       [--out out/bench_iteration.csv]
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core, as the paper's figure

import argparse  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import open3d as o3d  # noqa: E402

import o3d_spectral  # noqa: E402
from o3d_spectral.harness.writers import write_rows  # noqa: E402
from o3d_spectral.spectra import fft, so3  # noqa: E402
from o3d_spectral.spectra.target_grid import PRECISION  # noqa: E402
from o3d_spectral.synthetic import models  # noqa: E402

PAPER_MS = 8.7


def _median_ms(function, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return 1000.0 * float(np.median(times))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--object", default="mustard_bottle")
    parser.add_argument("--iterations", type=int, default=50, help="iterations per run (>= 20)")
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--voxel-size", type=float, default=0.008)
    parser.add_argument("--bandwidth", type=int, default=16)
    parser.add_argument("--out", type=Path, help="write the figures here as one CSV row")
    args = parser.parse_args()

    o3d.utility.random.seed(0)
    source = models.load_model(args.object).sample_points_uniformly(20000, use_triangle_normal=True)
    T = np.eye(4)
    T[:3, :3] = so3.exp([0.3, -0.2, 0.4])
    T[:3, 3] = [0.03, -0.02, 0.01]
    target = o3d.geometry.PointCloud(source).transform(T)
    option = o3d_spectral.SpectralRegistrationOption(bandwidth=args.bandwidth)
    stepper = o3d_spectral.SpectralStepper(target, args.voxel_size, option=option)
    moving = stepper.moving(source)

    def one_run() -> list[float]:
        """The law from the identity, ``iterations`` times (no early stop), as
        ``law.climb`` runs it: from the second iteration the translation is searched in
        the window about the previous prediction."""
        R, t, per_iteration, predicted = np.eye(3), np.zeros(3), [], None
        for _ in range(args.iterations):
            start = time.perf_counter()
            evaluation = stepper.evaluate(
                moving, R, t, level=stepper.levels - 1, around=predicted
            )
            predicted = moving.centroid + t + evaluation.translation
            dR, dt = stepper.increments(evaluation)
            R, t = so3.project_to_rotation(R @ dR), t + dt
            per_iteration.append(time.perf_counter() - start)
        return per_iteration

    one_run()  # warm-up: FFT plans, caches
    run_medians = [1000.0 * float(np.median(one_run())) for _ in range(args.runs)]
    iteration_ms = float(np.median(run_medians))

    grid_box = stepper.grid.moving_box(moving.radius, moving.centroid)
    block = stepper.grid.search_box(moving.radius, around=moving.centroid)
    shape = stepper.grid.fft_shape(block, grid_box, moving.radius)  # the iterations' FFT grid
    plan = fft.fft_plan(shape, precision=PRECISION)  # the iterations' precision
    grid = np.random.default_rng(0).random(shape).astype(plan.dtype)
    spectrum = np.array(plan.forward(grid))
    two_ffts_ms = _median_ms(lambda: (plan.forward(grid), plan.inverse(spectrum)),
                             args.runs * args.iterations)

    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores "
          f"(1 thread used), Python {platform.python_version()}, FFT backend {fft.backend(shape)}")
    print(f"object {args.object}, voxel {1000 * args.voxel_size:.0f} mm, B = {args.bandwidth}, "
          f"FFT grid {shape[0]}x{shape[1]}x{shape[2]}, {len(moving.points)} source voxels")
    print(f"{'':32s}{'ms':>9s}")
    print(f"{'one iteration (median)':32s}{iteration_ms:9.2f}   "
          f"(medians of {args.runs} runs x {args.iterations} iterations: "
          + ", ".join(f"{m:.2f}" for m in run_medians) + ")")
    print(f"{'two 3D FFTs of the same grid':32s}{two_ffts_ms:9.2f}")
    print(f"{'paper (C++, FFTW, FFTSO3)':32s}{PAPER_MS:9.2f}")
    print(f"iteration / two FFTs = {iteration_ms / two_ffts_ms:.2f}x;  "
          f"iteration / paper = {iteration_ms / PAPER_MS:.2f}x")
    if args.out:
        write_rows(args.out, [{
            "object": args.object, "voxel_m": args.voxel_size, "bandwidth": args.bandwidth,
            "fft_grid": "x".join(map(str, shape)), "fft_backend": fft.backend(shape),
            "source_voxels": len(moving.points), "iterations": args.iterations,
            "runs": args.runs, "iteration_ms": iteration_ms,
            "run_medians_ms": " ".join(f"{m:.4f}" for m in run_medians),
            "two_ffts_ms": two_ffts_ms, "paper_ms": PAPER_MS}])


if __name__ == "__main__":
    main()
