"""Figures of a registration run (matplotlib, imported lazily: the ``harness`` extra)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from .common import extras
from .common.pose_errors import rotation_error, translation_error
from .law.loop import IterationRecord

__all__ = ["pyplot", "convergence_errors", "plot_convergence"]


def pyplot():
    """``matplotlib.pyplot`` on the non-interactive Agg backend, with an install hint."""
    extras.require("matplotlib", "plotting").use("Agg")
    return extras.require("matplotlib.pyplot", "plotting")


def convergence_errors(
    history: Sequence[IterationRecord],
    ground_truth: ArrayLike,
    *,
    center: ArrayLike | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Rotation (degrees) and translation (metres) error of each iteration's estimate.

    Parameters
    ----------
    history : sequence of IterationRecord
    ground_truth : array_like, shape (4, 4)
        Source-to-target transformation.
    center : array_like, shape (3,), optional
        Source point at which translation errors are measured (the source frame's origin
        when omitted; see :func:`o3d_spectral.common.pose_errors.translation_error`).

    Returns
    -------
    rotation_deg, translation_m : ndarray, shape (len(history),)
    """
    T = np.asarray(ground_truth, dtype=np.float64)
    rot = [rotation_error(h.transformation, T) for h in history]
    trans = [translation_error(h.transformation, T, center=center) for h in history]
    return np.asarray(rot), np.asarray(trans)


def plot_convergence(
    history: Sequence[IterationRecord],
    path: str | Path,
    *,
    ground_truth: ArrayLike | None = None,
    center: ArrayLike | None = None,
    title: str = "",
    final: ArrayLike | None = None,
) -> Path:
    """Save the paper's Fig. 2: errors (or costs) against iteration, as a PNG.

    With ``ground_truth`` the panels show the translation (mm) and rotation (degrees)
    errors (translation at the source point ``center``); without, the costs ``J_t`` and
    ``J_r``. A third panel shows both gradient norms. With ``ground_truth`` and ``final``
    (the transformation returned, after the refinement that follows the law), the error
    panels end with its errors, a distinct marker one step after the last iteration.

    Returns
    -------
    pathlib.Path
        The file written.
    """
    plt = pyplot()
    it = np.array([h.iteration for h in history])
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.4))
    if ground_truth is not None:
        rot, trans = convergence_errors(history, ground_truth, center=center)
        panels = [(trans * 1000, "translation error (mm)"), (rot, "rotation error (deg)")]
    else:
        panels = [
            ([h.cost_translation for h in history], "$J_t$"),
            ([h.cost_rotation for h in history], "$J_r$"),
        ]
    for ax, (values, label) in zip(axes[:2], panels, strict=True):
        ax.plot(it, values, "o-", ms=3, label="law")
        ax.set_xlabel("iteration")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    if ground_truth is not None and final is not None:
        after = (it[-1] if len(it) else 0) + 1
        final_errors = (1000 * translation_error(final, ground_truth, center=center),
                        rotation_error(final, ground_truth))
        for ax, value in zip(axes[:2], final_errors, strict=True):
            ax.plot([after], [value], "*", ms=10, color="C3", label="result (refined)")
            ax.legend()
    ax = axes[2]
    ax.semilogy(it, [h.translation_gradient_norm * 1000 for h in history], label="|grad T| (mm)")
    ax.semilogy(it, [np.rad2deg(h.rotation_gradient_norm) for h in history],
                label="rotation step (deg)")
    ax.set_xlabel("iteration")
    ax.legend()
    ax.grid(alpha=0.3)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
