"""``o3d-spectral register SOURCE TARGET --voxel-size V``: align two cloud files."""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import logging
import os
import re
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np

EXAMPLE = "example: o3d-spectral register model.ply scan.pcd --voxel-size 0.008 --json"
#: Extensions of the files Open3D writes a point cloud to.
SAVE_FORMATS = (".ply", ".pcd", ".pts", ".xyz", ".xyzn", ".xyzrgb")

log = logging.getLogger(__name__)


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
    parser.add_argument(
        "--voxel-size", type=_voxel_size, required=True, metavar="METRES|auto|rule",
        help="voxel edge, metres; 'rule': read off the clouds' point spacing and extent "
        "(o3d_spectral.suggest_voxel_size), one registration; 'auto': the rule's size and 1.4 "
        "times it, and 0.75 times it unless those two agree on the pose, the pose the "
        "sizes agree on kept (o3d_spectral.voxel_trial: two or three registrations, their "
        "time in docs/conventions.md; with --init, the rule's); the size is logged and "
        "in the --json output",
    )
    parser.add_argument(
        "--init", type=Path, metavar="FILE",
        help="text file with a 4x4 initial transformation (then a local registration)",
    )
    parser.add_argument("--bandwidth", type=int, default=16, help="EGI bandwidth B (l < B)")
    parser.add_argument("--max-iteration", type=int, default=100,
                        help="most iterations of the law (per hypothesis when global)")
    parser.add_argument("--json", action="store_true",
                        help="print one JSON object instead (the only thing on stdout)")
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
                        help="write the source moved by the result (" + ", ".join(SAVE_FORMATS)
                        + "); its folder is checked before the registration runs")
    _add_search_arguments(parser)
    parser.add_argument(
        "--drop-nan", action="store_true",
        help="drop points with NaN or infinite coordinates (with a warning) instead of "
        "refusing the file",
    )
    parser.set_defaults(func=run, status=True)


def _add_search_arguments(parser: argparse.ArgumentParser) -> None:
    """``--device`` and ``--rotations``: where and how the global search runs."""
    parser.add_argument(
        "--device", type=_device, default=None, metavar="CPU:0|CUDA:N",
        help="where the global search's correlations run: CPU:0 (default) or CUDA:N (CuPy: "
        "pip install 'o3d-spectral[gpu]'; the search is then dense)",
    )
    parser.add_argument(
        "--rotations", choices=("auto", "adaptive", "dense", "escalating"), default="auto",
        help="how the global search sweeps SO(3) where its first candidates are not "
        "confirmed (GlobalSearchOption.rotations): 'auto' (default) escalates on the CPU "
        "(the dense search too where the pose may be wrong) and is dense on a GPU; "
        "'dense' on every call; 'adaptive' never dense",
    )


def _voxel_size(text: str) -> float | str:
    """``--voxel-size``: "auto", "rule", or a number (checked as a voxel size before any
    file is read: a NaN or a negative number is refused naming the option)."""
    if text.strip().lower() in ("auto", "rule"):
        return text.strip().lower()
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"a number of metres, 'auto' or 'rule', got {text!r}") from None


def _device(text: str) -> str:
    """``--device``: a device's name, read as the calls read it (a typo is a usage
    error); whether CUDA is usable is checked when the search starts."""
    from o3d_spectral.correlation.device import parse_device

    try:
        return str(parse_device(text, "--device"))
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error).removeprefix("--device ")) from None


@contextlib.contextmanager
def _open3d_failures() -> Iterator[list[str]]:
    """The reading failures Open3D reports during the block (it returns what it read so
    far, and tells Python nothing), as a list filled when the block ends.

    Open3D's Python module prints its messages through ``sys.stdout``: they are caught
    there (at least its warnings, whatever the verbosity) and passed on when the
    verbosity shows them, except the failures, which the caller reports."""
    import open3d as o3d

    level = o3d.utility.get_verbosity_level()
    shown = level.value >= o3d.utility.VerbosityLevel.Warning.value
    caught, printed_to = io.StringIO(), sys.stdout
    failures: list[str] = []
    sys.stdout = caught
    if not shown:
        o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Warning)
    try:
        yield failures
    finally:
        sys.stdout = printed_to
        o3d.utility.set_verbosity_level(level)
        for line in caught.getvalue().splitlines(keepends=True):
            text = re.sub(r"\x1b\[[0-9;]*m", "", line).strip()
            if text.startswith("[Open3D WARNING]") and "failed" in text.lower():
                failures.append(text.removeprefix("[Open3D WARNING]").strip())
            elif shown:
                printed_to.write(line)


def _read_cloud(path: Path, *, drop_nan: bool = False):
    """The cloud in ``path``: its points (and normals), or a mesh file's vertices (and
    vertex normals). Refuses a missing, truncated or corrupt file (also one Open3D reads
    only in part) and non-finite points (``drop_nan``: drops those, with a warning),
    naming the file."""
    import open3d as o3d

    from o3d_spectral.io.files import check_cloud_file, check_finite

    check_cloud_file(path)
    with _open3d_failures() as failures:
        cloud = o3d.io.read_point_cloud(str(path))
    if failures and len(cloud.points):
        raise ValueError(f"{path}: Open3D read it only in part ({'; '.join(failures)})")
    if len(cloud.points) == 0:  # a mesh file: use its vertices and normals
        with _open3d_failures() as mesh_failures:
            mesh = o3d.io.read_triangle_mesh(str(path))
        if len(mesh.vertices) == 0:
            why = "; ".join(dict.fromkeys(failures + mesh_failures))  # each once
            raise ValueError(f"{path}: Open3D read no points from it" + (f" ({why})" if why
                                                                          else ""))
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
    from o3d_spectral.common.checks import check_transformation

    if not path.is_file():
        raise FileNotFoundError(f"--init: no such file: {path}")
    try:
        init = np.loadtxt(path, dtype=np.float64, ndmin=2)
    except ValueError as error:
        raise ValueError(f"--init {path}: not a 4x4 matrix of numbers ({error})") from None
    if init.shape != (4, 4):
        rows, columns = init.shape
        raise ValueError(f"--init {path}: not a 4x4 matrix: {rows} rows of {columns} numbers")
    bad = np.argwhere(~np.isfinite(init))
    if len(bad):
        where = ", ".join(f"row {r + 1} column {c + 1}" for r, c in bad[:4])
        more = f" and {len(bad) - 4} more" if len(bad) > 4 else ""
        raise ValueError(f"--init {path}: {len(bad)} of its 16 numbers are not finite "
                         f"(NaN or infinite): {where}{more}")
    return check_transformation(init, name=f"--init {path}")


def _check_save(path: Path, inputs: tuple[Path, ...]) -> None:
    """Refuse ``--save FILE`` before any work when Open3D could not write it: an
    extension it does not write, a folder that does not exist or cannot be written to,
    or a folder in its place; or when it is one of the ``inputs`` (it would replace it)."""
    from o3d_spectral.cli import UsageError

    for given in inputs:
        if path.resolve() == given.resolve():
            raise UsageError(f"--save {path} is an input of the command ({given}): saving "
                             "there would replace it; choose another file")

    if path.suffix.lower() not in SAVE_FORMATS:
        raise UsageError(f"--save {path}: Open3D writes a point cloud to "
                         f"{', '.join(SAVE_FORMATS)} files, not {path.suffix or 'no extension'}")
    folder = path.parent
    if not folder.is_dir():
        raise FileNotFoundError(f"--save {path}: no such folder: {folder}")
    if path.is_dir():
        raise IsADirectoryError(f"--save {path}: a folder, not a file")
    if not os.access(folder, os.W_OK | os.X_OK) or (path.exists()
                                                  and not os.access(path, os.W_OK)):
        raise PermissionError(f"--save {path}: not allowed to write there")


def _save(path: Path, cloud) -> None:
    """Write ``--save``'s cloud whole, or not at all (``OSError`` naming it)."""
    import open3d as o3d

    from o3d_spectral.io.files import atomic_write_cloud

    try:
        atomic_write_cloud(path, len(cloud.points),
                           lambda name: o3d.io.write_point_cloud(name, cloud))
    except OSError as error:
        raise OSError(f"--save: {error}") from None
    log.info("wrote %s", path)


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


def _read_logged(path: Path, drop_nan: bool):
    """:func:`_read_cloud`, logging what was read and how long it took."""
    start = time.perf_counter()
    cloud = _read_cloud(path, drop_nan=drop_nan)
    log.info("read %s: %d points%s in %.2f s", path, len(cloud.points),
             " with normals" if cloud.has_normals() else "", time.perf_counter() - start)
    return cloud


def _summary(result, voxel_size: float) -> dict:
    """The result and the voxel size used (metres) as JSON values (``--json``)."""
    return {
        "transformation": result.transformation.tolist(),
        "voxel_size": voxel_size,
        "fitness": result.fitness,
        "fit": result.fit,
        "rival_fit": result.rival_fit,
        "inlier_rmse": result.inlier_rmse,
        "max_correspondence_distance": result.max_correspondence_distance,
        "converged": result.converged,
        "num_iterations": result.num_iterations,
        "run_time": result.run_time,
        "confidence": result.confidence,
        "ambiguity_deg": result.ambiguity,
        "ambiguous_transformation": None if result.ambiguous_transformation is None
        else result.ambiguous_transformation.tolist(),
        "source_normals": _reading(result.source_reading),
        "target_normals": _reading(result.target_reading),
        "target_viewpoint": None if result.target_viewpoint is None
        else result.target_viewpoint.tolist(),
        "warnings": result.warnings,
        "notes": result.notes,
    }


def run(args: argparse.Namespace) -> int:
    import open3d as o3d

    import o3d_spectral
    from o3d_spectral.cli import UsageError, results
    from o3d_spectral.common.checks import check_voxel_size

    auto = args.voxel_size in ("auto", "rule")
    if not auto:
        try:
            check_voxel_size(args.voxel_size, "--voxel-size")  # before reading any file
        except ValueError as error:
            raise UsageError(str(error)) from None
    if args.save:
        _check_save(args.save, tuple(p for p in (args.source, args.target, args.init) if p))
    init = _read_init(args.init) if args.init else None
    source, target = (_read_logged(path, args.drop_nan) for path in (args.source, args.target))
    voxel_size = o3d_spectral.suggest_voxel_size(source, target) if auto else args.voxel_size
    trial = args.voxel_size == "auto" and init is None
    if auto and not trial:
        log.info("--voxel-size %s: %.4g m (from the clouds' point spacing and extent)",
                 args.voxel_size, voxel_size)
    result, voxel_size = _registered(args, source, target, init, voxel_size, trial)
    if not np.all(np.isfinite(result.transformation)):  # never print a pose that is not one
        raise FloatingPointError("the registration produced a non-finite transformation")
    log.info("registered in %.2f s: fitness %.3f, inlier rmse %.4f m, %d iterations",
             result.run_time, result.fitness, result.inlier_rmse, result.num_iterations)
    summary = _summary(result, voxel_size)
    if args.save:
        _save(args.save, o3d.geometry.PointCloud(source).transform(result.transformation))
    out = results()
    if args.json:
        json.dump(summary, out, indent=2)
        print(file=out)
    else:
        np.savetxt(out, result.transformation, fmt="%.9f")
        print(
            f"confidence {result.confidence:.3f}  fitness {result.fitness:.4f}  "
            f"fit {result.fit:.4f}  inlier_rmse {result.inlier_rmse:.6f} m  "
            f"(at {result.max_correspondence_distance:.4g} m)  converged {result.converged}  "
            f"iterations {result.num_iterations}  time {result.run_time:.3f} s"
            + (f"  voxel_size {voxel_size:.4g} m ({args.voxel_size})" if auto else ""),
            file=out,
        )
    return 0


def _registered(
    args: argparse.Namespace, source, target, init: np.ndarray | None, voxel_size: float,
    trial: bool,
):
    """The registration the arguments ask for, and the voxel size it ran at (metres):
    the law from ``init``; the global search at ``voxel_size``; or, with ``trial``, the
    global search at the sizes of :func:`o3d_spectral.voxel_trial`, the pose they agree
    on kept."""
    import o3d_spectral

    option = o3d_spectral.SpectralRegistrationOption(bandwidth=args.bandwidth)
    criteria = o3d_spectral.SpectralConvergenceCriteria(max_iteration=args.max_iteration)
    cloud = o3d_spectral.CloudOption(camera_location=args.camera_location,
                                     target_viewpoint=_viewpoint(args.target_viewpoint),
                                     source_camera_location=args.source_camera_location)
    search = o3d_spectral.GlobalSearchOption(rotations=args.rotations)
    log.info("registering %s onto %s at %g m voxels%s, bandwidth %d: %s", args.source.name,
             args.target.name, voxel_size, " first (voxel size by trial)" if trial else "",
             args.bandwidth,
             "the law from --init" if init is not None else "global search over SO(3)")
    if init is not None:
        return o3d_spectral.registration_spectral(
            source, target, voxel_size, init, option, criteria, cloud=cloud
        ), voxel_size
    if trial:
        began = time.perf_counter()
        chosen = o3d_spectral.voxel_trial(source, target, option=option, criteria=criteria,
                                          search=search, cloud=cloud, device=args.device)
        result, voxel_size = chosen.result, chosen.voxel_size
        log.info("--voxel-size auto: %.4g m, confidence %.3f (tried %s; %.2f s in all)",
                 voxel_size, result.confidence,
                 ", ".join(f"{v:.4g} m: {c:.3f}" for v, c in chosen.tried),
                 time.perf_counter() - began)
        return result, voxel_size
    return o3d_spectral.registration_spectral_global(
        source, target, voxel_size, option, criteria, search=search, cloud=cloud,
        device=args.device
    ), voxel_size
