"""Figures of a servoing run (matplotlib on the Agg backend: the ``harness`` extra)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..plots import pyplot
from .loop import ServoRun
from .scene import Sensor, Tabletop

__all__ = ["plot_convergence", "plot_trajectory", "plot_snapshots"]

_MAX_POINTS = 3000  # per cloud in the snapshots


def _save(fig, path: str | Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    pyplot().close(fig)
    return path


def plot_convergence(run: ServoRun, path: str | Path) -> Path:
    """Translation (mm) and rotation (degrees) errors of the camera against time, with
    the law's corrections (the stop test's terms), log scale. Returns the PNG path."""
    plt = pyplot()
    t = np.array([c.time for c in run.cycles])
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.4))
    for ax, error, correction, unit, scale in (
        (axes[0], "translation_error", "translation_correction", "mm", 1000.0),
        (axes[1], "rotation_error", "rotation_correction", "deg", 180.0 / np.pi),
    ):
        ax.semilogy(t, [scale * getattr(c, error) for c in run.cycles], "o-", ms=3,
                    label="error to the desired pose")
        ax.semilogy(t, [scale * getattr(c, correction) for c in run.cycles], "s--", ms=2,
                    alpha=0.7, label="law's full correction")
        ax.set_xlabel("time (s)")
        ax.set_ylabel(f"{error.split('_')[0]} ({unit})")
        ax.grid(alpha=0.3, which="both")
    axes[0].legend(fontsize=8)
    return _save(fig, path)


def plot_trajectory(run: ServoRun, scene: Tabletop, path: str | Path) -> Path:
    """The camera's 3D path (world frame) above the table's objects. Returns the PNG path."""
    plt = pyplot()
    positions = np.array([c.world_from_camera[:3, 3] for c in run.cycles])
    fig = plt.figure(figsize=(5.5, 5))
    ax = fig.add_subplot(projection="3d")
    for mesh in scene.meshes[1:]:
        vertices = np.asarray(mesh.vertices)[:: 20]
        ax.scatter(*vertices.T, s=0.5, c="0.6")
    ax.plot(*positions.T, "-o", ms=2, label="camera path")
    ax.scatter(*positions[0], s=40, c="tab:red", label="start")
    ax.scatter(*run.desired_pose[:3, 3], s=60, marker="*", c="tab:green", label="desired")
    for pose, colour in ((run.cycles[0].world_from_camera, "tab:red"),
                         (run.desired_pose, "tab:green")):
        ax.quiver(*pose[:3, 3], *(0.1 * pose[:3, 2]), color=colour)  # optical axis
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("z (m)")
    ax.set_aspect("equal")
    ax.legend(fontsize=8, loc="upper left")
    return _save(fig, path)


def _subsample(points: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    if len(points) <= _MAX_POINTS:
        return points
    return points[rng.choice(len(points), _MAX_POINTS, replace=False)]


def plot_snapshots(
    run: ServoRun, scene: Tabletop, sensor: Sensor, path: str | Path, *, seed: int = 0
) -> Path:
    """The paper's Fig. 5: start, middle and final clouds against the reference.

    Each panel shows, in camera coordinates seen from above the image plane, the cloud
    captured at the reference pose (grey) and the one the camera sees at that cycle
    (coloured by depth), re-captured from the recorded poses with fresh noise drawn from
    ``seed``. Returns the PNG path.
    """
    plt = pyplot()
    rng = np.random.default_rng(seed)
    reference = _subsample(sensor.capture(scene, run.desired_pose, rng=rng)[:, :3], rng)
    picks = {"start": run.cycles[0], "middle": run.cycles[len(run.cycles) // 2],
             "final": run.final}
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.9), sharex=True, sharey=True)
    for ax, (label, cycle) in zip(axes, picks.items(), strict=True):
        current = _subsample(sensor.capture(scene, cycle.world_from_camera, rng=rng)[:, :3], rng)
        ax.scatter(reference[:, 0], reference[:, 1], s=0.3, c="0.7", label="reference")
        ax.scatter(current[:, 0], current[:, 1], s=0.3, c=current[:, 2], cmap="viridis",
                   label="current")
        ax.set_title(f"{label}: t = {cycle.time:.1f} s, {1000 * cycle.translation_error:.1f} "
                     f"mm, {np.rad2deg(cycle.rotation_error):.2f} deg", fontsize=9)
        ax.set_xlabel("x (m, camera)")
        ax.set_aspect("equal")
    axes[0].set_ylabel("y (m, camera)")
    axes[0].invert_yaxis()  # image rows grow downwards
    axes[0].legend(markerscale=15, fontsize=8, loc="lower left")
    return _save(fig, path)
