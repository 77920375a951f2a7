"""Regression check for refactors: the same transformations as a recorded reference.

Runs the local call (the law from the identity) and the global call (the search over all
of SO(3)) with default settings on the first N instances of each group of
``eval/bench_speed.py`` (the four suites, crops in their scene, the wide tabletop and the
real cases, one seeded rotation each), and either records their transformations
with their confidences and what each call said (its warnings and notes) (``--record``),
or compares them with a recording (``--compare``), reporting the largest absolute
difference per group and call and the calls whose words changed. A
behaviour-preserving change gives differences at rounding level (under 1e-9) and the
same words.

Usage:
    o3d-spectral make-suite full --n 12 --seed 0 --out suites12/full   # and the others
    python eval/check_unchanged.py --suites suites12 --record eval/reference/unchanged.npz
    python eval/check_unchanged.py --suites suites12 --compare eval/reference/unchanged.npz
       [--groups full dragon_24 ...] [--count 12]

``eval/reference/unchanged.npz`` holds such a recording: 12 instances a group (every real
case once), the commit it was recorded at inside.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import numpy as np
import open3d as o3d
from bench_speed import ALL_GROUPS, group_tasks

import o3d_spectral

TOLERANCE = 1e-9
#: The calls compared: name -> function(source, target, voxel) -> result.
CALLS = {
    "local": o3d_spectral.registration_spectral,
    "global": o3d_spectral.registration_spectral_global,
}


def run(suites: Path, count: int, groups: tuple[str, ...] = ALL_GROUPS) -> dict[str, np.ndarray]:
    """Per ``"<group>/<call>"``: the transformations (count, 4, 4); per
    ``"<group>/<call>/confidence"`` their confidences (count,); per ``"<group>/<call>/said"``
    each call's warnings and notes, one string a call (count,)."""
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    out = {}
    for group in groups:
        tasks = group_tasks(group, suites, rotations=1, limit=count)
        for call_name, call in CALLS.items():
            results = [call(t.source, t.target, t.voxel) for t in tasks]
            key = f"{group}/{call_name}"
            out[key] = np.stack([np.asarray(r.transformation) for r in results])
            out[f"{key}/confidence"] = np.array([r.confidence for r in results])
            out[f"{key}/said"] = np.array(["\n".join([*r.warnings, *r.notes]) for r in results])
            print(f"{group:14s} {call_name:7s} {len(tasks)} done", flush=True)
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--suites", type=Path, required=True, help="folder of the four suites")
    parser.add_argument("--count", type=int, default=12, help="instances per group")
    parser.add_argument("--groups", nargs="+", choices=ALL_GROUPS, default=ALL_GROUPS)
    group = parser.add_mutually_exclusive_group(required=True)
    group.add_argument("--record", type=Path, metavar="NPZ")
    group.add_argument("--compare", type=Path, metavar="NPZ")
    parser.add_argument("--save", type=Path, metavar="NPZ",
                        help="with --compare: also write this run's transformations")
    args = parser.parse_args()
    found = run(args.suites, args.count, tuple(args.groups))
    if args.save:
        np.savez_compressed(args.save, **found)
    if args.record:
        commit = subprocess.run(
            ["git", "rev-parse", "HEAD"], capture_output=True, text=True, check=False
        ).stdout.strip()
        args.record.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(args.record, commit=commit, **found)
        print(f"recorded {len(found) // 3} groups and calls at commit {commit} to {args.record}")
        return 0
    reference = np.load(args.compare)
    print(f"reference recorded at commit {reference['commit']}")
    worst, reworded = 0.0, 0
    for key, value in found.items():
        if key not in reference:
            print(f"{key:20s} not in the reference")
            worst = worst if key.endswith(("/confidence", "/said")) else np.inf
            continue
        expected = reference[key]
        n = min(len(expected), len(value))
        if key.endswith("/said"):
            changed = int(np.sum(expected[:n] != value[:n]))
            reworded += changed
            print(f"{key:27s} {n:3d} instances  {changed} said otherwise")
            continue
        per_instance = np.abs(expected[:n] - value[:n]).reshape(n, -1).max(axis=1, initial=0.0)
        diff = float(per_instance.max())
        worst = max(worst, diff)
        changed = int(np.sum(per_instance > TOLERANCE))
        print(f"{key:27s} {n:3d} instances  max |difference| {diff:.3g}  "
              f"({changed} over {TOLERANCE:g})")
    print(f"largest difference {worst:.3g} ({'within' if worst <= TOLERANCE else 'over'} "
          f"{TOLERANCE:g}); {reworded} calls said otherwise")
    return 0 if worst <= TOLERANCE and not reworded else 1


if __name__ == "__main__":
    sys.exit(main())
