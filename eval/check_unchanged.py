"""Regression check for refactors: the same transformations as a recorded reference.

Runs the local call (the law from the identity) and the global call (the search over all
of SO(3)) with default settings on the first N instances of each suite, and either
records their transformations (``--record``) or compares them with a recording
(``--compare``), reporting the largest absolute difference per suite and call. A
behaviour-preserving change gives differences at rounding level (under 1e-9).

Usage:
    o3d-spectral make-suite full --n 30 --seed 0 --out suites30/full   # and the others
    python eval/check_unchanged.py --suites suites30 --record eval/reference/unchanged.npz
    python eval/check_unchanged.py --suites suites30 --compare eval/reference/unchanged.npz
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import numpy as np
import open3d as o3d

import o3d_spectral
from o3d_spectral.synthetic.suite import load_suite

CONDITIONS = ("full", "partial", "occluded", "cluttered")
VOXEL_SIZE = 0.008
TOLERANCE = 1e-9


def _calls():
    """The calls compared: name -> function(source, target) -> 4x4 transformation."""
    return {
        "local": lambda s, t: o3d_spectral.registration_spectral(s, t, VOXEL_SIZE),
        "global": lambda s, t: o3d_spectral.registration_spectral_global(s, t, VOXEL_SIZE),
    }


def run(suites: Path, count: int) -> dict[str, np.ndarray]:
    """Transformations (count, 4, 4) per ``"<condition>/<call>"``."""
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    out = {}
    for condition in CONDITIONS:
        suite = load_suite(suites / condition)
        instances = [suite[i] for i in range(min(count, len(suite)))]
        for call_name, call in _calls().items():
            out[f"{condition}/{call_name}"] = np.stack(
                [np.asarray(call(i.source, i.target).transformation) for i in instances]
            )
            print(f"{condition:10s} {call_name:7s} {len(instances)} done", flush=True)
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--suites", type=Path, required=True, help="folder of the four suites")
    parser.add_argument("--count", type=int, default=30, help="instances per suite")
    group = parser.add_mutually_exclusive_group(required=True)
    group.add_argument("--record", type=Path, metavar="NPZ")
    group.add_argument("--compare", type=Path, metavar="NPZ")
    parser.add_argument("--save", type=Path, metavar="NPZ",
                        help="with --compare: also write this run's transformations")
    args = parser.parse_args()
    found = run(args.suites, args.count)
    if args.save:
        np.savez_compressed(args.save, **found)
    if args.record:
        commit = subprocess.run(
            ["git", "rev-parse", "HEAD"], capture_output=True, text=True, check=False
        ).stdout.strip()
        args.record.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(args.record, commit=commit, **found)
        print(f"recorded {len(found)} groups at commit {commit} to {args.record}")
        return 0
    reference = np.load(args.compare)
    print(f"reference recorded at commit {reference['commit']}")
    worst = 0.0
    for key, value in found.items():
        expected = reference[key]
        n = min(len(expected), len(value))
        per_instance = np.abs(expected[:n] - value[:n]).reshape(n, -1).max(axis=1)
        diff = float(per_instance.max())
        worst = max(worst, diff)
        changed = int(np.sum(per_instance > TOLERANCE))
        print(f"{key:20s} {n:3d} instances  max |difference| {diff:.3g}  "
              f"({changed} over {TOLERANCE:g})")
    print(f"largest difference {worst:.3g} ({'within' if worst <= TOLERANCE else 'over'} "
          f"{TOLERANCE:g})")
    return 0 if worst <= TOLERANCE else 1


if __name__ == "__main__":
    sys.exit(main())
