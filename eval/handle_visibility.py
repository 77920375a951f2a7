"""Which views of the turntable pairs show the mug's handle: the data's own ambiguity.

A mug's body is a surface of revolution: a view that shows none of its handle fixes
nothing of the turn about the body's axis, and a pair of views in which one shows none of
it has no single right pose in the data, whatever the method (the benchmarks count it
right only within 5 degrees of the truth, the mug having no symmetry). For each mug
turntable pair of ``eval/recall_generators.py`` (the same angles, elevations and seeds:
``synthetic.turntable.turntable_pair``), this prints the share of each view's points
lying within ``--distance`` of the handle's surface (the model's surface sampled
uniformly, its handle the part farther than ``--radius`` from the body's vertical axis
through the model's centre). Prints a Markdown table; ``--out FILE`` also writes it as
CSV (``docs/data/handle_visibility.csv``, which ``tools/docs_figures.py`` renders in
``docs/benchmarks.md``)::

    python eval/handle_visibility.py --out docs/data/handle_visibility.csv
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import open3d as o3d
from scipy.spatial import cKDTree

from o3d_spectral.harness.writers import write_rows
from o3d_spectral.synthetic.models import model_names
from o3d_spectral.synthetic.sampling import model_mesh
from o3d_spectral.synthetic.turntable import TURNTABLE_ANGLES, TURNTABLE_ELEVATIONS, turntable_pair

#: Seed of the pair at index ``k`` of the (elevation, model) list, as the recall script
#: draws them.
SEED = 200
#: Points sampled on the model's surface to find its handle.
SURFACE_POINTS = 200_000


def handle_tree(radius: float) -> cKDTree:
    """A KD-tree of the mug's surface points farther than ``radius`` (metres) from its
    vertical axis through the mean of its vertices (metres, the model's frame)."""
    mesh = model_mesh("mug")
    centre = np.asarray(mesh.vertices).mean(axis=0)
    o3d.utility.random.seed(SEED)  # Open3D's sampling draws from its own generator
    points = np.asarray(mesh.sample_points_uniformly(SURFACE_POINTS).points)
    return cKDTree(points[np.linalg.norm(points[:, :2] - centre[:2], axis=1) > radius])


def handle_share(cloud, world_from_camera: np.ndarray, tree: cKDTree, distance: float) -> float:
    """The share of ``cloud``'s points (a view in its camera's frame) within ``distance``
    (metres) of the handle once moved into the model's frame."""
    pose = np.asarray(world_from_camera)
    points = np.asarray(cloud.points) @ pose[:3, :3].T + pose[:3, 3]
    nearest, _ = tree.query(points, distance_upper_bound=distance)
    return float(np.mean(np.isfinite(nearest)))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--radius", type=float, default=0.052,
                        help="handle: the surface farther than this from the axis, metres")
    parser.add_argument("--distance", type=float, default=0.002,
                        help="a view's point shows the handle within this of it, metres")
    parser.add_argument("--out", type=Path, help="also write the table here (CSV)")
    args = parser.parse_args(argv)
    rows = []
    tree = handle_tree(args.radius)
    pairs = [(name, elevation) for elevation in TURNTABLE_ELEVATIONS for name in model_names()]
    print("| degrees apart | elevation | source view | target view |")
    print("| --- | --- | --- | --- |")
    for angle in TURNTABLE_ANGLES:
        for index, (name, elevation) in enumerate(pairs):
            if name != "mug":
                continue
            pair = turntable_pair(name, angle, elevation, np.random.default_rng(SEED + index))
            source_pose, target_pose = pair.metadata["world_from_cameras"]
            shares = [handle_share(pair.source, source_pose, tree, args.distance),
                      handle_share(pair.target, target_pose, tree, args.distance)]
            print(f"| {angle} | {elevation} | " + " | ".join(f"{100 * s:.1f}%" for s in shares)
                  + " |")
            rows.append({"angle": angle, "elevation": elevation, "source_share": shares[0],
                         "target_share": shares[1]})
    if args.out is not None:
        write_rows(args.out, rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
