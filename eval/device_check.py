"""The global search's correlations on a GPU: CuPy's peaks against NumPy's, and the times.

Two steps on two machines, the second without Open3D (the correlation layer needs NumPy
and CuPy alone):

    python eval/device_check.py prepare --out eval/device_inputs            # here
    python eval/device_check.py run --inputs eval/device_inputs --out OUT   # on the GPU

``prepare`` writes, for one instance of each of ``--groups`` (two dragon pairs, a
turntable pair, a YCB-Video frame by default), ``<group>.npz``: the fixed grids and the
turned moving cloud of the dense search's two grids (where the moving cloud spans about
16 cells, and the placement's), the FFT shapes, the dense search's rotations and the
rotation of the dense call's pose; and ``cpu.json``: on this machine, the dense global
call's seconds and success, the seconds of
its sweep's correlations (:func:`sweep`, the work the GPU takes over) and the lean
FPFH-RANSAC's seconds.

``run`` (``--xp cupy``, or ``numpy`` to try it anywhere) prints and writes ``table.md``
and ``results.json``, per instance: the largest relative difference between the peak
heights of the backend and of NumPy (``ArrayBackend(numpy)``, the reference) over 512
rotations, the dense call's among them, and whether the same 8 rotations rank first; the
milliseconds a rotation at the placement's grid by batch size; the milliseconds of all
the dense rotations at that grid; the seconds of the dense sweep's correlations (coarse
ranking, then the best 128 at the placement's grid); and the dense call with those on
the device, ``cpu call - cpu correlations + device correlations``, against the lean
FPFH-RANSAC's CPU seconds. Times are medians of ``--repeats``.
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # the package from this checkout, installed or not

from o3d_spectral.correlation import ArrayBackend, BatchedCorrelation, TurnedCloud  # noqa: E402

GROUPS = ("dragon_96", "dragon_120", "turntable_135", "ycbv_crop")
#: Rotations compared between the backends, and ranked first in both.
COMPARED, TOP = 512, 8
#: Batch sizes timed at the placement's grid (0: the backend's own choice).
BATCHES = (1, 8, 32, 128, 0)
#: The dense search's rotations re-ranked on the placement's grid (its ``RERANKED``; the
#: run step imports nothing of the search, which needs Open3D).
RERANKED = 128


# ------------------------------------------------------------------------- prepare


def _grids(stepper, moving, factor: float) -> dict:
    """The fixed grid, the turned cloud and the FFT shape of a grid of ``factor`` voxels,
    as :func:`o3d_spectral.search.candidates.turned_correlation` builds them."""
    from o3d_spectral.search.candidates import turned_correlation

    correlation, cloud = turned_correlation(stepper, moving, factor)
    grid = stepper.grid.coarsened(factor)
    normals = cloud.normals if cloud.culled else np.zeros((0, 3))
    viewpoint = cloud.viewpoint if cloud.culled else np.zeros(3)
    return {"fixed": grid.values, "moving_shape": np.array(correlation.moving_shape),
            "shape": np.array(correlation.shape), "sigma": np.array(grid.peak_width),
            "points": cloud.points, "offset": cloud.offset, "normals": normals,
            "viewpoint": viewpoint, "two_sided": np.array(cloud.two_sided),
            "min_facing": np.array(cloud.min_facing), "weighting": np.array(cloud.weighting)}


def prepare(groups: list[str], out: Path, repeats: int) -> None:
    import bench_dense
    import bench_speed as speed

    import o3d_spectral
    from o3d_spectral.correlation import CompiledBackend
    from o3d_spectral.search.candidates import span_factor
    from o3d_spectral.search.dense import COARSE_SPAN, dense_rotations
    from o3d_spectral.search.dense import RERANKED as SEARCH_RERANKED
    from o3d_spectral.search.placement import placement_factor
    from o3d_spectral.search.situation import situation

    assert RERANKED == SEARCH_RERANKED, "RERANKED is the dense search's"
    out.mkdir(parents=True, exist_ok=True)
    timings = {}
    for group in groups:
        task = speed.group_tasks(group, None, 1, 1)[0]
        stepper = o3d_spectral.SpectralStepper(task.target, task.voxel)
        moving = stepper.moving(task.source)
        two_scans = situation(stepper, moving).two_scans
        _, rotations = dense_rotations(stepper, moving, 4608, two_scans=two_scans)
        coarse = span_factor(stepper.voxel_size, moving.radius, COARSE_SPAN)
        fine = placement_factor(stepper.voxel_size, moving.radius, two_scans=two_scans)
        arrays = {f"coarse_{k}": v for k, v in _grids(stepper, moving, coarse).items()}
        arrays |= {f"fine_{k}": v for k, v in _grids(stepper, moving, fine).items()}
        start = time.perf_counter()
        search = o3d_spectral.GlobalSearchOption(rotations="dense")
        result = o3d_spectral.registration_spectral_global(task.source, task.target,
                                                           task.voxel, search=search)
        dense_s = time.perf_counter() - start
        swept = "sweep" in result.stage_times  # else confirmed first: no dense sweep ran
        pose = np.asarray(result.transformation)
        start = time.perf_counter()
        bench_dense.variants([], [])["lean"](task)
        lean_s = time.perf_counter() - start
        np.savez_compressed(out / f"{group}.npz", rotations=rotations,
                            found=pose[:3, :3], **arrays)
        data = np.load(out / f"{group}.npz")
        correlations = _seconds(lambda data=data: sweep(data, CompiledBackend()), repeats)
        timings[group] = {"dense_s": dense_s, "dense_success": bool(task.score(pose)[2]),
                          "swept": swept, "sweep_correlations_s": correlations,
                          "lean_s": lean_s}
        print(f"{group}: {len(rotations)} rotations, grids {arrays['coarse_shape'].tolist()} "
              f"and {arrays['fine_shape'].tolist()}; {timings[group]}", flush=True)
    (out / "cpu.json").write_text(json.dumps(timings, indent=1) + "\n")


def sweep(data, backend) -> None:
    """The dense search's correlations, on every core where the backend runs batches on
    threads (as the call does): every rotation on the coarse grid, the best
    :data:`RERANKED` on the placement's (:func:`o3d_spectral.search.dense.dense_candidates`;
    where both grids are one, every rotation on it; the compass search left out)."""
    coarse, coarse_cloud = _correlation(data, "coarse", backend)
    fine, fine_cloud = _correlation(data, "fine", backend)
    rotations = data["rotations"]
    if np.array_equal(data["coarse_shape"], data["fine_shape"]):
        fine.peaks(fine_cloud, rotations, None)
        return
    heights = coarse.peaks(coarse_cloud, rotations, None).heights
    fine.peaks(fine_cloud, rotations[np.argsort(-heights, kind="stable")[:RERANKED]], None)


# ----------------------------------------------------------------------------- run


def _correlation(data, grid: str, backend) -> tuple[BatchedCorrelation, TurnedCloud]:
    get = {k.removeprefix(f"{grid}_"): data[k] for k in data.files if k.startswith(grid)}
    culled = len(get["normals"]) > 0
    cloud = TurnedCloud(get["points"], get["offset"],
                        normals=get["normals"] if culled else None,
                        viewpoint=get["viewpoint"] if culled else None,
                        two_sided=bool(get["two_sided"]), min_facing=int(get["min_facing"]),
                        weighting=str(get["weighting"]))
    correlation = BatchedCorrelation(get["fixed"], tuple(get["moving_shape"].tolist()),
                                     shape=tuple(get["shape"].tolist()),
                                     sigma=float(get["sigma"]), backend=backend)
    return correlation, cloud


def _seconds(call, repeats: int) -> float:
    call()  # the first call builds the plans and compiles the kernels
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        call()
        times.append(time.perf_counter() - start)
    return float(np.median(times))


class _Batched(ArrayBackend):
    """The backend with a fixed batch size."""

    def __init__(self, xp, device, size: int) -> None:
        super().__init__(xp, device)
        self.size = size

    def batch_size(self, shape):
        return self.size or super().batch_size(shape)


def check_case(path: Path, xp, device: int | None, repeats: int, cpu: dict) -> dict:
    data = np.load(path)
    rotations = data["rotations"]
    picked = np.concatenate([data["found"][None], rotations[:: max(1, len(rotations)
                                                                   // (COMPARED - 1))]])
    reference = _correlation(data, "fine", ArrayBackend(np))
    tested = _correlation(data, "fine", ArrayBackend(xp, device))
    ref, got = (c.peaks(cloud, picked).heights for c, cloud in (reference, tested))
    row = {"instance": path.stem, "rotations": len(rotations),
           "max_relative_difference": float(np.max(np.abs(got - ref) / np.abs(ref))),
           "same_first": bool(np.array_equal(np.argsort(-got, kind="stable")[:TOP],
                                             np.argsort(-ref, kind="stable")[:TOP]))}
    for size in BATCHES:
        correlation, cloud = _correlation(data, "fine", _Batched(xp, device, size))
        block = rotations[: max(size, 64)]
        row[f"ms_per_rotation_batch_{size or 'auto'}"] = 1e3 * _seconds(
            lambda correlation=correlation, cloud=cloud, block=block:
            correlation.peaks(cloud, block), repeats) / len(block)
    fine, fine_cloud = _correlation(data, "fine", ArrayBackend(xp, device))
    row["all_rotations_fine_ms"] = 1e3 * _seconds(lambda: fine.peaks(fine_cloud, rotations),
                                                  repeats)
    row["sweep_s"] = _seconds(lambda: sweep(data, ArrayBackend(xp, device)), repeats)
    measured = cpu.get(path.stem)
    if measured:
        call = measured["dense_s"]  # confirmed before the sweep: the GPU changes nothing
        if measured["swept"]:
            call += row["sweep_s"] - measured["sweep_correlations_s"]
        row |= {"dense_call_s": call, "lean_ransac_s": measured["lean_s"],
                "ratio_to_lean": call / measured["lean_s"],
                "dense_success": measured["dense_success"]}
    return row


def markdown(rows: list[dict]) -> str:
    head = ("| instance | peaks: max rel. diff | same first 8 | ms/rotation (batch 1 / auto) "
            "| all rotations (ms) | sweep (s) | dense call, sweep here (s) | lean (s) | ratio |")
    lines = [head, "|" + " --- |" * 9]
    for r in rows:
        lines.append(
            f"| {r['instance']} ({r['rotations']}) | {r['max_relative_difference']:.1e} | "
            f"{'yes' if r['same_first'] else 'NO'} | {r['ms_per_rotation_batch_1']:.3f} / "
            f"{r['ms_per_rotation_batch_auto']:.3f} | {r['all_rotations_fine_ms']:.1f} | "
            f"{r['sweep_s']:.3f} | {r.get('dense_call_s', float('nan')):.3f} | "
            f"{r.get('lean_ransac_s', float('nan')):.3f} | "
            f"{r.get('ratio_to_lean', float('nan')):.2f} |")
    return "\n".join(lines) + "\n"


def run(inputs: Path, out: Path, xp_name: str, device: int, repeats: int) -> None:
    xp = importlib.import_module(xp_name)
    gpu = None if xp is np else device
    cpu_file = inputs / "cpu.json"
    cpu = json.loads(cpu_file.read_text()) if cpu_file.is_file() else {}
    rows = [check_case(path, xp, gpu, repeats, cpu) for path in sorted(inputs.glob("*.npz"))]
    table = markdown(rows)
    print(table, end="")
    out.mkdir(parents=True, exist_ok=True)
    (out / "table.md").write_text(table)
    (out / "results.json").write_text(json.dumps({"xp": xp_name, "rows": rows}, indent=1))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    steps = parser.add_subparsers(dest="step", required=True)
    made = steps.add_parser("prepare", help="write the inputs (needs Open3D)")
    made.add_argument("--groups", nargs="+", default=list(GROUPS))
    made.add_argument("--out", type=Path, default=ROOT / "eval" / "device_inputs")
    made.add_argument("--repeats", type=int, default=3)
    checked = steps.add_parser("run", help="compare and time (NumPy and CuPy alone)")
    checked.add_argument("--inputs", type=Path, default=ROOT / "eval" / "device_inputs")
    checked.add_argument("--out", type=Path, required=True)
    checked.add_argument("--xp", default="cupy", help="the array library (cupy, numpy)")
    checked.add_argument("--device", type=int, default=0, help="the GPU's index")
    checked.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    if args.step == "prepare":
        prepare(args.groups, args.out, args.repeats)
    else:
        run(args.inputs, args.out, args.xp, args.device, args.repeats)
    return 0


if __name__ == "__main__":
    sys.exit(main())
