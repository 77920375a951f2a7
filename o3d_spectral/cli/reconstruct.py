"""``o3d-spectral reconstruct SCAN... --voxel-size V --out DIR``: many scans, one model.

Registers the scans into the first one's frame with
:func:`o3d_spectral.registration_multiway` (no initial poses) and writes to ``DIR``:
``merged.ply`` (every placed scan moved by its pose, merged, thinned to half the voxel),
``poses.json`` (the settings, each file's 4x4 pose, the unconnected and the doubtful
files, the pairs) and ``merged.png`` (the merged cloud coloured by scan, seen along its
principal axes).
The three are written to temporary files in ``DIR`` and renamed once all are written:
a failed run leaves none of them half written; a previous run's three wait in
``DIR/previous_run/`` until the new ones are complete, so that a run interrupted leaves
no set that looks complete. One run at a time writes ``DIR``
(:mod:`~o3d_spectral.io.folder_lock`). Scans the registration refuses before
any work (in different units, too few points) are a usage error, named by file (exit 2).
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import re
import shutil
import tempfile
from pathlib import Path

import numpy as np

from .constants import PICTURE_POINTS

EXAMPLE = ("example: o3d-spectral reconstruct scan_*.ply --voxel-size 0.005 --out model "
           "--json")
OUTPUTS = ("merged.ply", "poses.json", "merged.png")
#: Where a new run moves the outputs of the previous one until it has written its own.
PREVIOUS = "previous_run"

log = logging.getLogger(__name__)


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "reconstruct",
        help="register many scans (no initial poses) and merge them into one cloud",
        description="Register SCANs, in any frames, into the first scan's frame "
        "(registration_multiway: pairwise global registrations and a pose graph); write "
        "the merged cloud (PLY), the poses (JSON) and a picture coloured by scan (PNG) "
        "to --out. A scan that matches none of the others is reported, not placed.",
        epilog=EXAMPLE,
    )
    parser.add_argument("scans", type=Path, nargs="+", metavar="SCAN",
                        help="two or more clouds (any file Open3D reads), metres")
    parser.add_argument("--voxel-size", type=float, required=True, metavar="METRES",
                        help="voxel edge of the registrations, metres")
    parser.add_argument("--out", type=Path, required=True, metavar="DIR",
                        help="folder for " + ", ".join(OUTPUTS) + " (made if missing)")
    parser.add_argument("--workers", type=int, default=None,
                        help="threads of the pairwise registrations (default: all cores)")
    parser.add_argument("--sensor-frames", action="store_true",
                        help="each scan is in its camera's frame, the camera at the origin "
                        "(depth frames, fragments in their first camera's frame): no scan "
                        "is placed where another's camera saw empty space")
    parser.add_argument("--json", action="store_true",
                        help="print the poses as one JSON object (the only thing on stdout)")
    parser.set_defaults(func=run, status=True)


def _check_args(args: argparse.Namespace) -> None:
    """Usage errors, before any file is read."""
    from o3d_spectral.cli import UsageError

    if len(args.scans) < 2:
        raise UsageError(f"SCAN: give at least two scans to register, got {len(args.scans)}")
    if not np.isfinite(args.voxel_size) or args.voxel_size <= 0:
        raise UsageError(f"--voxel-size must be a positive number of metres, got "
                         f"{args.voxel_size}")
    if args.workers is not None and args.workers < 1:
        raise UsageError(f"--workers must be at least 1, got {args.workers}")
    if args.out.exists() and not args.out.is_dir():
        raise UsageError(f"--out {args.out}: a file, not a folder")
    if len(set(args.scans)) < len(args.scans):
        raise UsageError("SCAN: a file is given twice")


def _read(path: Path):
    """The points of the cloud (or mesh vertices) in ``path``, refused naming the file
    when there are none."""
    import open3d as o3d

    from o3d_spectral.io.files import check_cloud_file

    check_cloud_file(path)
    cloud = o3d.io.read_point_cloud(str(path))
    if len(cloud.points) == 0:
        cloud = o3d.geometry.PointCloud(o3d.io.read_triangle_mesh(str(path)).vertices)
    if len(cloud.points) == 0:
        raise ValueError(f"{path}: Open3D read no points from it")
    return cloud


def _progress(args: argparse.Namespace):
    """A ``progress(done, total)`` callback: a tqdm bar on a terminal (when tqdm is
    installed), else INFO log lines."""
    from o3d_spectral.cli import show_progress

    if show_progress(args):
        try:
            from tqdm import tqdm
        except ImportError:
            tqdm = None
        if tqdm is not None:
            bar = tqdm(desc="pairs", unit="pair", leave=False)

            def update(done: int, total: int) -> None:
                bar.total = total
                bar.update(done - bar.n)
                if done == total:
                    bar.close()

            return update
    return lambda done, total: log.info("pairwise registrations: %d of %d", done, total)


def _merged(clouds: list, poses: tuple, voxel_size: float):
    """The placed clouds moved by their poses, merged and thinned to one point (the mean)
    per cell of half the voxel, and the scan index of each point (that of a point of its
    cell drawn at random, seeded: where scans overlap, each shows in the picture)."""
    import open3d as o3d

    whole, scans = o3d.geometry.PointCloud(), []
    for k, (cloud, pose) in enumerate(zip(clouds, poses, strict=True)):
        if pose is not None:
            whole += o3d.geometry.PointCloud(cloud).transform(pose)
            scans.append(np.full(len(cloud.points), k))
    merged, _, cells = whole.voxel_down_sample_and_trace(
        voxel_size / 2, whole.get_min_bound(), whole.get_max_bound())
    rng = np.random.default_rng(0)
    drawn = np.array([cell[rng.integers(len(cell))] for cell in cells], dtype=np.int64)
    return merged, np.concatenate(scans)[drawn]


def _picture(path: Path, points: np.ndarray, labels: np.ndarray, names: list[str]) -> None:
    """Two orthographic views of ``points`` (N, 3) along their principal axes (the
    plane of the two largest, and that of the largest and the smallest), coloured by
    ``labels``, to the PNG ``path`` (matplotlib's Agg canvas: headless)."""
    from matplotlib import colormaps
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

    order = np.random.default_rng(0).permutation(len(points))[:PICTURE_POINTS]
    points, labels = points[order], labels[order]  # shuffled: no scan drawn over the rest
    centred = points - points.mean(axis=0)
    points = centred @ np.linalg.eigh(np.cov(centred.T))[1][:, ::-1]  # largest axis first
    figure = Figure(figsize=(11, 4.5), dpi=80)
    FigureCanvasAgg(figure)
    colours = colormaps["tab10"]
    for column, (a, b, title) in enumerate(((0, 1, "principal axes 1, 2"),
                                            (0, 2, "principal axes 1, 3"))):
        axes = figure.add_subplot(1, 2, column + 1)
        axes.scatter(points[:, a], points[:, b], s=0.5, c=colours(labels % 10),
                     rasterized=True)
        axes.set_aspect("equal")
        axes.set_title(title)
        axes.set_xlabel("metres")
    scans = np.unique(labels)
    handles = [Line2D([], [], ls="", marker="o", color=colours(k % 10)) for k in scans]
    figure.legend(handles, [names[k] for k in scans], loc="center right", fontsize="small")
    figure.tight_layout(rect=(0.0, 0.0, 0.8, 1.0))
    figure.savefig(path)


def _write_ply(path: Path, cloud) -> None:
    import open3d as o3d

    if not o3d.io.write_point_cloud(str(path), cloud):
        raise OSError(f"{path}: Open3D could not write the merged cloud")


def _summary(args: argparse.Namespace, result) -> dict:
    """The settings, the poses, the unconnected and the doubtful scans and the pairs as
    JSON values."""
    names = [str(p) for p in args.scans]
    return {
        "voxel_size": args.voxel_size,
        "sensor_frames": args.sensor_frames,
        "poses": {name: None if pose is None else pose.tolist()
                  for name, pose in zip(names, result.poses, strict=True)},
        "unconnected": [names[k] for k in result.unconnected],
        "doubtful": [names[k] for k in result.doubtful],
        "pairs": [{"source": names[r.source], "target": names[r.target], "fit": r.fit,
                   "fitness": r.fitness, "confidence": r.confidence, "kept": r.kept}
                  for r in result.pairs],
        "run_time": result.run_time,
    }


def _write_all(out: Path, writers: dict) -> None:
    """Each ``writers[name](temporary path)`` into ``out``, then all renamed to their
    names: none is left half written (the temporaries are removed on a failure)."""
    out.mkdir(parents=True, exist_ok=True)
    umask = os.umask(0)
    os.umask(umask)
    written = {}
    try:
        for name, write in writers.items():
            handle, temporary = tempfile.mkstemp(dir=out, prefix=f".{Path(name).stem}-",
                                                 suffix=Path(name).suffix)
            os.close(handle)
            os.chmod(temporary, 0o666 & ~umask)  # as an ordinary new file, not 0600
            written[name] = Path(temporary)
            write(written[name])
        for name, temporary in written.items():
            os.replace(temporary, out / name)
    finally:
        for temporary in written.values():
            temporary.unlink(missing_ok=True)


def run(args: argparse.Namespace) -> int:
    from o3d_spectral.common.extras import require_modules
    from o3d_spectral.io.folder_lock import folder_lock

    _check_args(args)
    require_modules("this command", "matplotlib")
    with folder_lock(args.out, "o3d-spectral reconstruct"):  # one run at a time in --out
        _set_aside(args.out)
        register_and_write(args)
        shutil.rmtree(args.out / PREVIOUS, ignore_errors=True)  # the new set is complete
    return 0


def _set_aside(out: Path) -> None:
    """The outputs of a previous run in ``out`` moved into ``out/previous_run/`` (replacing
    what an older run left there), so that an interrupted run never leaves a set that
    looks complete."""
    found = [name for name in OUTPUTS if (out / name).exists()]
    if not found:
        return
    shutil.rmtree(out / PREVIOUS, ignore_errors=True)
    (out / PREVIOUS).mkdir()
    for name in found:
        os.replace(out / name, out / PREVIOUS / name)
    log.warning("moved the previous run's %s to %s until this one is complete",
                ", ".join(found), out / PREVIOUS)


def register_and_write(args: argparse.Namespace) -> None:
    """Register the scans, write the outputs, print the summary."""
    import o3d_spectral
    from o3d_spectral.cli import UsageError, results

    clouds = [_read(path) for path in args.scans]
    option = o3d_spectral.MultiwayOption(workers=args.workers, progress=_progress(args))
    try:
        cameras = [np.zeros(3)] * len(clouds) if args.sensor_frames else None
        result = o3d_spectral.registration_multiway(clouds, args.voxel_size, option=option,
                                                    camera_locations=cameras)
    except ValueError as error:  # scans refused before any work: named by file, exit 2
        if "clouds[" not in str(error):
            raise
        named = re.sub(r"clouds\[(\d+)\]", lambda m: str(args.scans[int(m.group(1))]),
                       str(error))
        raise UsageError(named) from None
    merged, labels = _merged(clouds, result.poses, args.voxel_size)
    summary = _summary(args, result)
    names = [p.name for p in args.scans]
    _write_all(args.out, {
        "merged.ply": lambda path: _write_ply(path, merged),
        "poses.json": lambda path: path.write_text(json.dumps(summary, indent=2) + "\n"),
        "merged.png": lambda path: _picture(path, np.asarray(merged.points), labels, names),
    })
    if args.json:
        print(json.dumps(summary), file=results())
    else:
        placed = len(args.scans) - len(result.unconnected)
        print(f"placed {placed} of {len(args.scans)} scans in {result.run_time:.1f} s; "
              f"wrote {', '.join(OUTPUTS)} to {args.out}", file=results())
        for k in result.unconnected:
            print(f"unconnected: {args.scans[k]}", file=results())
        for k in result.doubtful:
            print(f"doubtful (placed through pairs that may be wrong): {args.scans[k]}",
                  file=results())
