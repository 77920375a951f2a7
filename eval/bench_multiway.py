"""Multiway registration with no initial poses: the share of scans placed right.

Two sets of scans, each registered into its first scan's frame by
:func:`o3d_spectral.registration_multiway` (``spectral``) and by the same pose-graph
pipeline on pairs registered by lean FPFH-RANSAC (``fpfh_ransac_lean``,
:func:`o3d_spectral.multiway.registration.poses_from_pairs`; its pairs' ``fit`` is their fitness at
one voxel, no rival):

* ``dragon``: the Stanford dragon's eight turntable scans (5 mm voxel), each turned about
  its centroid by a seeded random rotation (one draw per seed, ``--seeds``);
* ``turntable``: for each bundled model, 8 depth views, a camera every 45 degrees of
  azimuth at 30 degrees of elevation, 0.45 m from the model's centre, each view in its own
  camera frame (8 mm voxel);
* ``room``: a synthetic furnished room's 12 fragments (``o3d_spectral.synthetic.room``,
  seed 300 + k for ``--rooms`` k), each in its first camera's frame, in a seeded random
  order (5 cm voxel): a room from unordered scans.

A scan is placed right when its pose is within 5 degrees and 1 cm (a room's fragment:
10 cm, two voxels) of the truth at its centroid, allowing a model's symmetry group (in
the first scan's frame: a symmetric object's scans are placed up to it). A turntable
view and a room's fragment are in their camera's frame: both pipelines are given the
cameras at the origin (``camera_locations``), and the same pairwise results are placed
again without them (the ``without cameras`` columns); the dragon's scans, turned, have
no known camera. Prints a
Markdown table, writes ``rows.csv`` (one row per scan), ``summary.csv`` and ``table.md``
to ``--out`` (``docs/data/multiway``:
``tools/docs_figures.py`` renders the table of ``docs/multiway.md`` from its
``summary.csv``)::

    python eval/bench_multiway.py --out docs/data/multiway
    python eval/bench_multiway.py --limit-scans 3 --models 1 --seeds 1 --out /tmp/mw
    python eval/bench_multiway.py --seeds 0 --models 0 --rooms 6 --out docs/data/multiway_room
"""

from __future__ import annotations

import argparse
import itertools
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import open3d as o3d
from scipy.spatial.transform import Rotation

import o3d_spectral
from o3d_spectral.harness import real
from o3d_spectral.harness.errors import symmetric_rotation_error, symmetric_translation_error
from o3d_spectral.harness.methods import get_method
from o3d_spectral.harness.writers import write_bench
from o3d_spectral.multiway.registration import pair_list, poses_from_pairs
from o3d_spectral.synthetic.camera import look_at, scan_meshes
from o3d_spectral.synthetic.instance import SceneOptions
from o3d_spectral.synthetic.models import model_names
from o3d_spectral.synthetic.room import RoomOptions, room_fragments
from o3d_spectral.synthetic.sampling import model_mesh
from o3d_spectral.synthetic.symmetry import Symmetry, model_symmetry

PIPELINES = ("spectral", "fpfh_ransac_lean")
DRAGON_VOXEL, TURNTABLE_VOXEL, ROOM_VOXEL = 0.005, 0.008, 0.05
VIEWS, AZIMUTH_STEP, ELEVATION, DISTANCE = 8, 45.0, 30.0, 0.45
MAX_ROTATION_DEG, MAX_TRANSLATION_M, ROOM_MAX_TRANSLATION_M = 5.0, 0.01, 0.1


def dragon_set(seed: int, limit: int) -> tuple[list, list, list]:
    """The dragon's first ``limit`` scans, each turned about its centroid by a random
    rotation drawn from ``seed``: (clouds, world_from_cloud poses, symmetries)."""
    rng = np.random.default_rng(seed)
    clouds, poses = [], []
    for angle in real.DRAGON_ANGLES[:limit]:
        path = real.real_dir() / "dragon" / f"dragonStandRight_{angle}.ply"
        cloud = o3d.io.read_point_cloud(str(path))
        centre = np.asarray(cloud.points).mean(axis=0)
        motion = np.eye(4)
        motion[:3, :3] = Rotation.random(random_state=rng).as_matrix()
        motion[:3, 3] = centre - motion[:3, :3] @ centre
        clouds.append(cloud.transform(motion))
        poses.append(real.dragon_pose(angle) @ np.linalg.inv(motion))
    return clouds, poses, [Symmetry()] * len(clouds)


def turntable_set(name: str, seed: int, limit: int) -> tuple[list, list, list]:
    """``limit`` depth views of the model ``name`` around it (module docstring), each in
    its camera's frame: (clouds, model_from_camera poses, symmetries in each camera's
    frame)."""
    rng = np.random.default_rng(seed)
    options = SceneOptions()
    mesh = model_mesh(name)
    centre = np.asarray(mesh.get_center())
    start, elevation = rng.uniform(0.0, 360.0), np.deg2rad(ELEVATION)
    clouds, poses = [], []
    for k in range(limit):
        azimuth = np.deg2rad(start + AZIMUTH_STEP * k)
        direction = np.array([np.cos(elevation) * np.cos(azimuth),
                              np.cos(elevation) * np.sin(azimuth), np.sin(elevation)])
        pose = look_at(centre + DISTANCE * direction, centre, up=(0.0, 0.0, 1.0))
        scan = scan_meshes([mesh], options.intrinsics, pose, noise=options.noise, rng=rng)
        clouds.append(scan.to_point_cloud())
        poses.append(pose)
    symmetry = model_symmetry(name)
    return clouds, poses, [symmetry.transformed(np.linalg.inv(p)) for p in poses]


def room_set(seed: int, limit: int) -> tuple[list, list, list]:
    """The first ``limit`` fragments of the room of ``seed``, shuffled by ``seed``:
    (clouds, world_from_fragment poses, symmetries)."""
    fragments = room_fragments(RoomOptions(), seed)[:limit]
    order = np.random.default_rng(seed).permutation(len(fragments))
    clouds = [o3d.geometry.PointCloud(o3d.utility.Vector3dVector(fragments[k].points))
              for k in order]
    return clouds, [fragments[k].world_from_fragment for k in order], [Symmetry()] * len(order)


def fpfh_records(clouds: list, voxel: float, seed: int) -> list:
    """Every pair registered by lean FPFH-RANSAC, as the multiway pipeline's records."""
    method = get_method("fpfh_ransac_lean")
    records = []
    option = o3d_spectral.MultiwayOption()
    for i, j in pair_list(len(clouds), option):
        transformation, _ = method(clouds[i], clouds[j], voxel, seed)
        evaluation = o3d.pipelines.registration.evaluate_registration(
            clouds[i].voxel_down_sample(voxel), clouds[j], voxel, transformation)
        records.append(o3d_spectral.PairwiseRecord(
            i, j, np.asarray(transformation, dtype=np.float64), evaluation.fitness,
            evaluation.fitness, 0.0, kept=False, uncertain=True))
    return records


def run_set(clouds: list, truths: list, symmetries: list, voxel: float, pipeline: str,
            seed: int, option: o3d_spectral.MultiwayOption, max_translation: float,
            sensor_frames: bool) -> tuple[list[dict], float]:
    """One set registered by ``pipeline``: a row per scan (errors, success: within
    :data:`MAX_ROTATION_DEG` and ``max_translation`` metres) and seconds. With
    ``sensor_frames`` the cameras are given at the origin, and the row says too whether
    the same pairs placed the scan right without them (``success_without_cameras``)."""
    cameras = [np.zeros(3)] * len(clouds) if sensor_frames else None
    start = time.perf_counter()
    if pipeline == "spectral":
        result = o3d_spectral.registration_multiway(clouds, voxel, option=option,
                                                    camera_locations=cameras)
        records = list(result.pairs)
    else:
        records = fpfh_records(clouds, voxel, seed)
        result = poses_from_pairs(clouds, voxel, records, option=option,
                                  camera_locations=cameras)
    seconds = time.perf_counter() - start
    blind = poses_from_pairs(clouds, voxel, records, option=option) if sensor_frames else None
    rows = []
    for k, cloud in enumerate(clouds):
        centre = np.asarray(cloud.points).mean(axis=0)
        truth = np.linalg.inv(truths[0]) @ truths[k]
        rotation, translation = _errors(result.poses[k], truth, symmetries[k], centre)
        rows.append({"scan": k, "rotation_error_deg": rotation,
                     "translation_error_m": translation,
                     "success": _right(rotation, translation, max_translation),
                     "unconnected": k in result.unconnected,
                     "doubtful": k in result.doubtful,
                     "success_without_cameras": "" if blind is None else _right(
                         *_errors(blind.poses[k], truth, symmetries[k], centre),
                         max_translation)})
    return rows, seconds


def _errors(pose: np.ndarray | None, truth: np.ndarray, symmetry: Symmetry,
            centre: np.ndarray) -> tuple[float, float]:
    """A scan's rotation (degrees) and translation (metres, at ``centre``) errors up to
    its ``symmetry``; NaN for a scan not placed."""
    if pose is None:
        return float("nan"), float("nan")
    return (symmetric_rotation_error(pose, truth, symmetry),
            symmetric_translation_error(pose, truth, symmetry, center=centre))


def _right(rotation: float, translation: float, max_translation: float) -> bool:
    """Within :data:`MAX_ROTATION_DEG` and ``max_translation`` (NaN: not placed)."""
    return bool(rotation < MAX_ROTATION_DEG and translation < max_translation)


def sets(args: argparse.Namespace):
    """Yields (suite, name, seed, clouds, truths, symmetries, voxel, the largest
    translation error of a scan placed right, whether each scan is in its camera's
    frame)."""
    for seed in range(args.seeds):
        yield ("dragon", f"seed {seed}", seed, *dragon_set(seed, args.limit_scans or VIEWS),
               DRAGON_VOXEL, MAX_TRANSLATION_M, False)
    for m, name in enumerate(model_names()[:args.models]):
        yield ("turntable", name, m, *turntable_set(name, m, args.limit_scans or VIEWS),
               TURNTABLE_VOXEL, MAX_TRANSLATION_M, True)
    for k in range(args.rooms):
        yield ("room", f"room {300 + k}", 300 + k,
               *room_set(300 + k, args.limit_scans or RoomOptions.fragments), ROOM_VOXEL,
               ROOM_MAX_TRANSLATION_M, True)


def summary(rows: list[dict], times: dict) -> list[dict]:
    """Per suite, set and pipeline: scans right out of scans, and seconds; then per
    suite and pipeline over its sets."""
    out = []
    for key, group in itertools.groupby(rows, lambda r: (r["suite"], r["set"], r["pipeline"])):
        group = list(group)
        blind = [r["success_without_cameras"] for r in group]
        out.append({"suite": key[0], "set": key[1], "pipeline": key[2],
                    "right": sum(r["success"] for r in group), "scans": len(group),
                    "seconds": times[key], **_doubts(group),
                    "right_without_cameras": "" if "" in blind else sum(blind)})
    for suite, pipeline in dict.fromkeys((r["suite"], r["pipeline"]) for r in rows):
        group = [s for s in out if (s["suite"], s["pipeline"]) == (suite, pipeline)]
        blind = [s["right_without_cameras"] for s in group]
        out.append({"suite": suite, "set": "all", "pipeline": pipeline,
                    "right": sum(s["right"] for s in group),
                    "scans": sum(s["scans"] for s in group),
                    "seconds": sum(s["seconds"] for s in group),
                    **{k: sum(s[k] for s in group) for k in DOUBTS},
                    "right_without_cameras": "" if "" in blind else sum(blind)})
    return out


#: The summary's counts of doubtful scans (``MultiwayResult.doubtful``): all of them, the
#: wrong ones among them, and the placed scans that are wrong but not doubtful.
DOUBTS = ("doubtful", "doubtful_wrong", "wrong_undoubted")


def _doubts(rows: list[dict]) -> dict[str, int]:
    """The :data:`DOUBTS` counts of a set's rows."""
    placed = [r for r in rows if not r["unconnected"]]
    return {"doubtful": sum(r["doubtful"] for r in placed),
            "doubtful_wrong": sum(r["doubtful"] and not r["success"] for r in placed),
            "wrong_undoubted": sum(not r["doubtful"] and not r["success"] for r in placed)}


def table(rows: list[dict], command: str, commit: str) -> str:
    """The Markdown table: one line per suite and set, both pipelines side by side."""
    by_key = {(s["suite"], s["set"], s["pipeline"]): s for s in rows}
    lines = ["| suite | set | " + " | ".join(f"{p}: right | {p}: s" for p in PIPELINES)
             + " | spectral: doubtful (wrong) | spectral: wrong, not doubtful | "
             + " | ".join(f"{p}: right without cameras" for p in PIPELINES) + " |",
             "|---|---|" + "---:|---:|" * len(PIPELINES) + "---:|---:|"
             + "---:|" * len(PIPELINES)]
    suites = list(dict.fromkeys(s["suite"] for s in rows))
    keys = sorted(dict.fromkeys((s["suite"], s["set"]) for s in rows),
                  key=lambda key: (suites.index(key[0]), key[1] == "all"))
    for suite, name in keys:
        cells = []
        for pipeline in PIPELINES:
            s = by_key.get((suite, name, pipeline))
            cells += ([f"{s['right']}/{s['scans']} ({100 * s['right'] / s['scans']:.0f}%)",
                       f"{s['seconds']:.1f}"] if s else ["-", "-"])
        s = by_key.get((suite, name, "spectral"))
        cells += ([f"{s['doubtful']} ({s['doubtful_wrong']})", str(s["wrong_undoubted"])]
                  if s else ["-", "-"])
        for pipeline in PIPELINES:
            s = by_key.get((suite, name, pipeline))
            blind = "" if s is None else s["right_without_cameras"]
            cells.append("-" if blind == "" else f"{blind}/{s['scans']}")
        label = f"**{name}**" if name == "all" else name
        lines.append(f"| {suite} | {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + f"\n\nProduced by `{command}` at commit {commit}.\n"


def _commit() -> str:
    """The short hash of the checked-out commit, or "unknown" outside a git checkout."""
    done = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                          text=True, cwd=Path(__file__).parent, check=False)
    return done.stdout.strip() or "unknown"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=3, help="random turns of the dragon")
    parser.add_argument("--models", type=int, default=len(model_names()),
                        help="the first this many bundled models (sorted by name)")
    parser.add_argument("--rooms", type=int, default=0, help="synthetic rooms")
    parser.add_argument("--limit-scans", type=int, default=None,
                        help=f"scans per set ({VIEWS}; a room's {RoomOptions.fragments})")
    parser.add_argument("--pipelines", nargs="+", choices=PIPELINES, default=list(PIPELINES))
    parser.add_argument("--workers", type=int, default=None, help="threads (all cores)")
    parser.add_argument("--refine", action="store_true",
                        help="MultiwayOption(refine=True): ICP from the optimised poses, "
                        "optimised again")
    parser.add_argument("--out", type=Path, required=True, help="folder for the outputs")
    args = parser.parse_args(argv)
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)  # stdout: the table
    if args.limit_scans is not None and args.limit_scans < 2:
        parser.error("--limit-scans must be at least 2")
    command = "python eval/bench_multiway.py " + " ".join(
        a for a in (argv if argv is not None else sys.argv[1:]))
    command = re.sub(r"--out \S+", "--out OUT", command)
    commit, rows, times = _commit(), [], {}
    option = o3d_spectral.MultiwayOption(workers=args.workers, refine=args.refine)
    for (suite, name, seed, clouds, truths, symmetries, voxel, max_translation,
         sensor_frames) in sets(args):
        for pipeline in args.pipelines:
            scans, seconds = run_set(clouds, truths, symmetries, voxel, pipeline, seed,
                                     option, max_translation, sensor_frames)
            times[(suite, name, pipeline)] = seconds
            rows += [{"suite": suite, "set": name, "pipeline": pipeline, **r} for r in scans]
            print(f"{suite} {name} {pipeline}: {sum(r['success'] for r in scans)}/"
                  f"{len(scans)} in {seconds:.1f} s", file=sys.stderr)
    summaries = summary(rows, times)
    text = table(summaries, command, commit)
    write_bench(args.out, rows, summaries, text, "table.md")
    print(text, end="")
    return 0


if __name__ == "__main__":
    sys.exit(main())
