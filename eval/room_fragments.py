"""Synthetic rooms as 3DMatch-style fragments, written in the geometric-registration
benchmark's layout so that ``o3d-spectral eval --pairs`` reads them.

Each seed draws one furnished room (:mod:`o3d_spectral.synthetic.room`) and writes its
fragments ``cloud_bin_<k>.ply`` (points only, metres, each in its first camera's frame),
``gt.log`` (the pairs overlapping over 30%, the transformation taking fragment ``j``
onto fragment ``i``) and ``gt.info`` (their information matrices, for the benchmark's
RMSE recall) to ``OUT/room_<seed>/``::

    python eval/room_fragments.py --seeds 0 1 2 --out /tmp/rooms
    o3d-spectral eval --pairs /tmp/rooms --voxel-size 0.05 \\
        --methods spectral_global fpfh_ransac_lean --out /tmp/rooms_eval
"""

from __future__ import annotations

import argparse
from pathlib import Path

import open3d as o3d

from o3d_spectral.harness.pairs import information_matrix, write_log
from o3d_spectral.synthetic.room import RoomOptions, fragment_pairs, room_fragments

#: The correspondence distance (m) of ``gt.info``'s information matrices: two of the
#: fragments' point spacings.
INFORMATION_DISTANCE = 0.02


def write_room(seed: int, out: Path, options: RoomOptions) -> int:
    """Write the room of ``seed`` to ``out / f"room_{seed}"``; returns its pairs' count."""
    folder = out / f"room_{seed}"
    folder.mkdir(parents=True, exist_ok=True)
    fragments = room_fragments(options, seed)
    clouds = [o3d.geometry.PointCloud(o3d.utility.Vector3dVector(f.points)) for f in fragments]
    for k, cloud in enumerate(clouds):
        o3d.io.write_point_cloud(str(folder / f"cloud_bin_{k}.ply"), cloud)
    pairs = fragment_pairs(fragments)
    write_log(folder / "gt.log", pairs, len(fragments))
    information = {(i, j): information_matrix(clouds[j], clouds[i], T, INFORMATION_DISTANCE)
                   for (i, j), T in pairs.items()}
    write_log(folder / "gt.info", information, len(fragments))
    return len(pairs)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0])
    parser.add_argument("--fragments", type=int, default=RoomOptions.fragments,
                        help="fragments a room, their first cameras spread over a turn")
    parser.add_argument("--frames-per-fragment", type=int,
                        default=RoomOptions.frames_per_fragment)
    parser.add_argument("--frame-step", type=float, default=RoomOptions.frame_step,
                        help="degrees the camera turns between two frames")
    parser.add_argument("--spacing", type=float, default=RoomOptions.spacing,
                        help="one point per cube of this many metres")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    options = RoomOptions(fragments=args.fragments, frames_per_fragment=args.frames_per_fragment,
                          frame_step=args.frame_step, spacing=args.spacing)
    for seed in args.seeds:
        print(f"room {seed}: {write_room(seed, args.out, options)} pairs")


if __name__ == "__main__":
    main()
