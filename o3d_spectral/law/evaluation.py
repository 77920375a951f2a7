"""The corrections and costs of one evaluation of the control law at a pose
(:meth:`o3d_spectral.SpectralStepper.evaluate`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..spectra.rotation import RotationGradient

__all__ = ["Evaluation"]


@dataclass(frozen=True)
class Evaluation:
    """Full corrections and costs at one pose of the moving cloud.

    Attributes
    ----------
    translation : ndarray, shape (3,)
        ``grad_glob T``: shift (metres, fixed frame) taking the moved cloud onto the fixed one.
    rotation : ndarray, shape (3,)
        Rotation step (radians) for a right perturbation ``R exp(hat(rotation))``.
    rotation_gradient : ndarray, shape (3,)
        The paper's ``grad C_r(R, e_k)``, before scaling.
    correlation : float
        ``C_r(R)`` of the normalised EGIs, in [-1/4pi, 1/4pi].
    translation_peak : float
        Height of the phase-correlation peak in [0, 1] (1: identical grids).
    cost_translation, cost_rotation : float
        ``J_t`` and ``J_r`` (eqs. translation_cost_function, rotation_cost_function) on
        unit-norm grids and coefficients, each in [0, 2].
    """

    translation: NDArray[np.float64]
    rotation: NDArray[np.float64]
    rotation_gradient: NDArray[np.float64]
    correlation: float
    translation_peak: float
    cost_translation: float
    cost_rotation: float

    @classmethod
    def of(
        cls, translation: NDArray[np.float64], rotation: NDArray[np.float64],
        local: RotationGradient, peak: float, cost_translation: float,
    ) -> Evaluation:
        """From the full corrections, the rotation correlation's derivatives ``local`` at
        the pose, the phase-correlation peak and ``J_t``."""
        return cls(
            translation=translation,
            rotation=rotation,
            rotation_gradient=local.gradient,
            correlation=local.value,
            translation_peak=peak,
            cost_translation=cost_translation,
            cost_rotation=float(1.0 - 4.0 * np.pi * local.value),
        )

    def within(self, tolerance: tuple[float, float]) -> bool:
        """Both full corrections below ``(metres, radians)`` (eq. updaterule's test)."""
        return bool(
            np.linalg.norm(self.translation) < tolerance[0]
            and np.linalg.norm(self.rotation) < tolerance[1]
        )
