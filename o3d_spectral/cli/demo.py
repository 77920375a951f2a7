"""``o3d-spectral demo``: register a bundled object to a moved partial view of itself."""

from __future__ import annotations

import argparse
import json
import logging
from pathlib import Path

import numpy as np

from .arguments import seed

log = logging.getLogger(__name__)


def _model_names() -> list[str]:
    """The bundled models' names, without importing Open3D (``--help`` stays quick);
    empty when no bundled models are found."""
    from o3d_spectral.common.bundled import bundled_folder

    try:
        folder = bundled_folder("objects", "O3D_SPECTRAL_DATA",
                                lambda f: f.is_dir() and any(f.glob("*.ply")), "object models")
    except FileNotFoundError:
        return []
    return sorted(p.stem for p in folder.glob("*.ply"))


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "demo",
        help="register a bundled object to a moved, noisy partial view of itself",
        description="Builds a partial depth-camera view of a bundled YCB object moved by a "
        "random rotation, registers the full model to it, prints the errors and the time, "
        "and writes them to OUT/result.json with the convergence plot (the paper's Fig. 2) "
        "when matplotlib is installed (the 'harness' extra). The plot follows the law's "
        "iterations; the errors printed are those of the result, after the final ICP "
        "polish, which the plot marks as its last point.",
        epilog="example: o3d-spectral demo --object mug --seed 3 --out out/demo",
    )
    names = _model_names()
    parser.add_argument(
        "--object", default="mustard_bottle", metavar="NAME",
        help="bundled model: " + (", ".join(names) if names else "none found (see "
                                  "O3D_SPECTRAL_DATA)"),
    )
    parser.add_argument("--seed", type=seed, default=0,
                        help="seed of the random rotation, offset, view and noise")
    parser.add_argument("--max-angle", type=float, default=30.0,
                        help="largest initial rotation, degrees (the law is local)")
    parser.add_argument("--voxel-size", type=float, default=0.008, help="metres")
    parser.add_argument("--out", type=Path, default=Path("out/demo"), help="output folder")
    parser.set_defaults(func=run, status=True)


def _per_iteration(history) -> float:
    """Median seconds between iterations (preparation excluded when there are several)."""
    times = np.array([h.time for h in history])
    return float(np.median(np.diff(times))) if len(times) > 1 else float(times[0])


def _errors(T, instance) -> dict[str, float]:
    """Errors of ``T`` against the instance's truth, plain and symmetry-aware (translation
    errors at the object's centroid)."""
    from o3d_spectral.harness import errors

    T_gt, center, symmetry = instance.T_gt, instance.source_center, instance.symmetry
    return {
        "rotation_error_deg": errors.rotation_error(T, T_gt),
        "translation_error_m": errors.translation_error(T, T_gt, center=center),
        "symmetric_rotation_error_deg": errors.symmetric_rotation_error(T, T_gt, symmetry),
        "symmetric_translation_error_m": errors.symmetric_translation_error(
            T, T_gt, symmetry, center=center
        ),
    }


def _plot(instance, result, args: argparse.Namespace) -> Path | None:
    """Write the convergence plot, ending at the polished result; None, after a one-line
    hint, without matplotlib."""
    from o3d_spectral import plots
    from o3d_spectral.common.extras import MissingExtraError

    try:
        return plots.plot_convergence(
            result.history, args.out / "convergence.png", ground_truth=instance.T_gt,
            center=instance.source_center,
            title=f"{args.object}: full model to a partial view "
            f"({instance.metadata['init_angle_deg']:.0f} deg initial rotation)",
            final=result.transformation,
        )
    except MissingExtraError as error:
        log.warning("no convergence plot: %s", error)
        return None


def run(args: argparse.Namespace) -> int:
    import o3d_spectral
    from o3d_spectral.cli import UsageError, results
    from o3d_spectral.synthetic.instance import SceneOptions
    from o3d_spectral.synthetic.scenes import make_instance

    if not 0 <= args.max_angle <= 180:
        raise UsageError(f"--max-angle must be in [0, 180] degrees, got {args.max_angle}")
    names = _model_names()
    if names and args.object not in names:
        raise UsageError(f"--object must be one of {', '.join(names)}; got {args.object!r}")
    options = SceneOptions(angle_range=(0.0, np.deg2rad(args.max_angle)), max_offset=0.05)
    instance = make_instance(
        "partial", args.object, rng=np.random.default_rng(args.seed), options=options
    )
    result = o3d_spectral.registration_spectral(instance.source, instance.target, args.voxel_size)
    errors = _errors(result.transformation, instance)
    args.out.mkdir(parents=True, exist_ok=True)
    figure = _plot(instance, result, args)
    law_rotation = _errors(result.history[-1].transformation, instance)["rotation_error_deg"]
    summary = {
        "config": {k: str(v) if isinstance(v, Path) else v for k, v in vars(args).items()
                   if k != "func"},
        "initial_rotation_deg": instance.metadata["init_angle_deg"],
        **errors,
        "converged": result.converged,
        "num_iterations": result.num_iterations,
        "run_time_s": result.run_time,
        "ms_per_iteration": 1000 * _per_iteration(result.history),
        "law_rotation_error_deg": law_rotation,
        "fitness": result.fitness,
        "transformation": result.transformation.tolist(),
        "ground_truth": instance.T_gt.tolist(),
        "convergence_plot": None if figure is None else str(figure),
    }
    (args.out / "result.json").write_text(json.dumps(summary, indent=2))
    written = " and ".join(str(f) for f in (figure, args.out / "result.json") if f is not None)
    print(
        f"{args.object}: initial rotation {summary['initial_rotation_deg']:.1f} deg, "
        f"partial view of {len(instance.target.points)} points\n"
        f"rotation error    {errors['rotation_error_deg']:.2f} deg "
        f"(symmetry-aware {errors['symmetric_rotation_error_deg']:.2f}) after the final "
        f"ICP polish; {law_rotation:.2f} deg at the law's last iteration\n"
        f"translation error {1000 * errors['translation_error_m']:.1f} mm at the centroid "
        f"(symmetry-aware {1000 * errors['symmetric_translation_error_m']:.1f})\n"
        f"{result.num_iterations} iterations, converged {result.converged}, "
        f"{result.run_time:.3f} s in all, {summary['ms_per_iteration']:.1f} ms per iteration\n"
        f"wrote {written}" + (" (the plot: the law's iterations, then the polished result)"
                              if figure is not None else ""), file=results(),
    )
    return 0
