"""Benchmark: a 2-million-point cloud registered by the local call, and where the time goes.

Two clouds of 2,000,000 points each, sampled uniformly (different seeds) on a sphere
0.5 m across with bumps of 10 and 5 cm (so that the rotation is defined) and 1 mm of
range noise, the second moved by
(1, -2, 1.5) cm and turned 5 degrees; ``o3d_spectral.registration_spectral`` at 1 cm
voxels from the identity, with the default polish. Prints the call's time, the pose
error and, with ``--profile``, the time of each stage (cProfile's cumulative seconds);
with ``--out``, writes the call's figures as one CSV row.

Usage: python eval/bench_large.py [--points 2000000] [--profile] [--out out/bench_large.csv]
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import time
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

import o3d_spectral
from o3d_spectral.harness.writers import write_rows

#: Range noise (metres, standard deviation) of the points, a scanner's.
NOISE = 0.001


def sphere(n: int, seed: int) -> np.ndarray:
    """``n`` points (metres) on a 0.25 m-radius sphere with two bumps, :data:`NOISE`
    along the radius."""
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    bump = sum(h * np.exp(-np.sum((u - axis) ** 2, axis=1) / 0.05)
               for h, axis in ((0.1, [0.0, 0.0, 1.0]), (0.05, [1.0, 0.0, 0.0])))
    return u * (0.25 + bump + rng.normal(0.0, NOISE, n))[:, None]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=2_000_000)
    parser.add_argument("--profile", action="store_true", help="print where the time goes")
    parser.add_argument("--out", type=Path, help="write the call's figures here as a CSV row")
    args = parser.parse_args()
    motion = np.eye(4)
    motion[:3, :3] = Rotation.from_euler("xyz", [3, -2, 3], degrees=True).as_matrix()
    motion[:3, 3] = [0.01, -0.02, 0.015]
    source = sphere(args.points, 0)
    target = sphere(args.points, 1) @ motion[:3, :3].T + motion[:3, 3]
    profile = cProfile.Profile()
    start = time.perf_counter()
    if args.profile:
        profile.enable()
    result = o3d_spectral.registration_spectral(source, target, 0.01)
    profile.disable()
    seconds = time.perf_counter() - start
    E = np.linalg.inv(motion) @ result.transformation
    angle = np.degrees(np.arccos(np.clip((np.trace(E[:3, :3]) - 1) / 2, -1, 1)))
    print(f"{args.points} points: {seconds:.1f} s; error {angle:.3f} deg, "
          f"{1000 * np.linalg.norm(E[:3, 3]):.2f} mm; fitness {result.fitness:.3f}")
    if args.out:
        write_rows(args.out, [{"points": args.points, "voxel_m": 0.01, "seconds": seconds,
                               "profiled": args.profile, "rotation_error_deg": angle,
                               "translation_error_mm": 1000 * np.linalg.norm(E[:3, 3]),
                               "fitness": result.fitness}])
    if not args.profile:
        return
    stats = pstats.Stats(profile)
    stats.sort_stats("tottime").print_stats(8)
    for name in ("start", "climb", "finish", "refined", "refine", "registration_icp",
                 "evaluate_registration", "representatives"):
        total = sum(v[3] for k, v in stats.stats.items() if k[2] == name)
        print(f"  {name:24s} {total:6.1f} s")


if __name__ == "__main__":
    main()
