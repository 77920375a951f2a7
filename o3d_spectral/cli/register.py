"""``o3d-spectral register SOURCE TARGET --voxel-size V``: align two cloud files."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

EXAMPLE = "example: o3d-spectral register model.ply scan.pcd --voxel-size 0.008 --json"


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "register",
        help="align SOURCE to TARGET and print the 4x4 transformation",
        description="Align SOURCE onto TARGET with spectral registration; prints the "
        "source-to-target 4x4 matrix and the fit. Without --init the rotation is searched "
        "over all of SO(3) (registration_spectral_global); with --init the paper's law "
        "runs from it (registration_spectral).",
        epilog=EXAMPLE,
    )
    parser.add_argument("source", type=Path, help="source cloud (any file Open3D reads)")
    parser.add_argument("target", type=Path, help="target cloud (any file Open3D reads)")
    parser.add_argument("--voxel-size", type=float, required=True, help="voxel edge, metres")
    parser.add_argument(
        "--init", type=Path,
        help="text file with a 4x4 initial transformation (then a local registration)",
    )
    parser.add_argument("--bandwidth", type=int, default=16, help="EGI bandwidth B (l < B)")
    parser.add_argument("--max-iteration", type=int, default=100)
    parser.add_argument("--json", action="store_true", help="print a JSON object instead")
    parser.add_argument(
        "--camera-location", type=float, nargs=3, metavar=("X", "Y", "Z"),
        help="where the sensor was (metres), to orient the normals estimated (or oriented "
        "again) for the target, and for the source unless --source-camera-location",
    )
    parser.add_argument(
        "--source-camera-location", type=float, nargs=3, metavar=("X", "Y", "Z"),
        help="where the source's sensor was (metres, source frame), when not the target's",
    )
    parser.add_argument(
        "--target-viewpoint", default="auto", metavar="auto|none|X,Y,Z",
        help="where the target's sensor was (metres, target frame) when it is a single view; "
        "'auto' (default): the origin when the target's normals face it, else a view "
        "recognised from its normals and depth; 'none': a model",
    )
    parser.add_argument("--save", type=Path, metavar="FILE",
                        help="write the source moved by the result (any format Open3D writes)")
    parser.add_argument(
        "--drop-nan", action="store_true",
        help="drop points with NaN or infinite coordinates (with a warning) instead of "
        "refusing the file",
    )
    parser.set_defaults(func=run)


def _read_cloud(path: Path, *, drop_nan: bool = False):
    """The cloud in ``path``: its points (and normals), or a mesh file's vertices (and
    vertex normals). Refuses a missing, truncated or corrupt file and non-finite points
    (``drop_nan``: drops those, with a warning), naming the file."""
    import open3d as o3d

    from o3d_spectral._files import check_cloud_file, check_finite

    check_cloud_file(path)
    cloud = o3d.io.read_point_cloud(str(path))
    if len(cloud.points) == 0:  # a mesh file: use its vertices and normals
        mesh = o3d.io.read_triangle_mesh(str(path))
        if len(mesh.vertices) == 0:
            raise ValueError(f"{path}: Open3D read no points from it")
        check_finite(np.asarray(mesh.vertices), path, what="vertices")
        mesh.compute_vertex_normals()
        cloud = o3d.geometry.PointCloud(mesh.vertices)
        cloud.normals = mesh.vertex_normals
    arrays = [np.asarray(cloud.points)]
    if cloud.has_normals():
        arrays.append(np.asarray(cloud.normals))
    what = "points (with their normals)" if len(arrays) == 2 else "points"
    keep = check_finite(np.hstack(arrays), path, drop=drop_nan, what=what,
                        hint="the file may be corrupt; --drop-nan drops them")
    if keep is not None:
        cloud = cloud.select_by_index(np.flatnonzero(keep).tolist())
        if len(cloud.points) == 0:
            raise ValueError(f"{path}: no point is left after dropping the non-finite ones")
    return cloud


def _read_init(path: Path) -> np.ndarray:
    """The 4x4 initial transformation in the text file ``path``, checked (and a nearly
    rigid one made rigid) as the library checks ``init``, errors naming option and file."""
    from o3d_spectral._checks import check_transformation

    if not path.is_file():
        raise FileNotFoundError(f"--init: no such file: {path}")
    try:
        init = np.loadtxt(path, dtype=np.float64, ndmin=2)
    except ValueError as error:
        raise ValueError(f"--init {path}: not a 4x4 matrix of numbers ({error})") from None
    return check_transformation(init, name=f"--init {path}")


def _viewpoint(text: str) -> str | tuple[float, ...] | None:
    """``--target-viewpoint``: "auto", None ("none") or three coordinates."""
    from o3d_spectral.cli import UsageError

    if text in ("auto", "none"):
        return None if text == "none" else text
    try:
        point = tuple(float(v) for v in text.split(","))
    except ValueError:
        point = ()
    if len(point) != 3:
        raise UsageError(f"--target-viewpoint must be auto, none or X,Y,Z, got {text!r}")
    return point


def _reading(reading) -> dict:
    """A CloudReading as JSON values."""
    view = None if reading.view is None else np.asarray(reading.view).tolist()
    return {"from": reading.normals_from, "orientation": reading.orientation, "view": view,
            "two_sided": reading.two_sided}


def run(args: argparse.Namespace) -> int:
    import open3d as o3d

    import o3d_spectral
    from o3d_spectral._checks import check_voxel_size

    check_voxel_size(args.voxel_size, "--voxel-size")  # before reading any file
    source = _read_cloud(args.source, drop_nan=args.drop_nan)
    target = _read_cloud(args.target, drop_nan=args.drop_nan)
    init = _read_init(args.init) if args.init else None
    option = o3d_spectral.SpectralRegistrationOption(bandwidth=args.bandwidth)
    criteria = o3d_spectral.SpectralConvergenceCriteria(max_iteration=args.max_iteration)
    cloud = o3d_spectral.CloudOption(camera_location=args.camera_location,
                                     target_viewpoint=_viewpoint(args.target_viewpoint),
                                     source_camera_location=args.source_camera_location)
    if init is not None:
        result = o3d_spectral.registration_spectral(
            source, target, args.voxel_size, init, option, criteria, cloud=cloud
        )
    else:
        result = o3d_spectral.registration_spectral_global(
            source, target, args.voxel_size, option, criteria, cloud=cloud
        )
    if not np.all(np.isfinite(result.transformation)):  # never print a pose that is not one
        raise FloatingPointError("the registration produced a non-finite transformation")
    summary = {
        "transformation": result.transformation.tolist(),
        "fitness": result.fitness,
        "inlier_rmse": result.inlier_rmse,
        "max_correspondence_distance": result.max_correspondence_distance,
        "converged": result.converged,
        "num_iterations": result.num_iterations,
        "run_time": result.run_time,
        "confidence": result.confidence,
        "source_normals": _reading(result.source_reading),
        "target_normals": _reading(result.target_reading),
        "target_viewpoint": None if result.target_viewpoint is None
        else result.target_viewpoint.tolist(),
        "warnings": result.warnings,
    }
    if args.save:
        moved = o3d.geometry.PointCloud(source).transform(result.transformation)
        if not o3d.io.write_point_cloud(str(args.save), moved):
            raise OSError(f"--save: Open3D could not write {args.save}")
    if args.json:
        json.dump(summary, sys.stdout, indent=2)
        print()
    else:
        np.savetxt(sys.stdout, result.transformation, fmt="%.9f")
        print(
            f"fitness {result.fitness:.4f}  inlier_rmse {result.inlier_rmse:.6f} m  "
            f"(at {result.max_correspondence_distance} m)  converged {result.converged}  "
            f"iterations {result.num_iterations}  time {result.run_time:.3f} s"
        )
    return 0
