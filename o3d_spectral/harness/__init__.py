"""Evaluation harness: spectral registration against Open3D's ICP, FPFH-RANSAC and FGR.

* :mod:`~o3d_spectral.harness.methods`: the methods, registered by name;
* :mod:`~o3d_spectral.harness.metrics`: per-instance errors and success;
* :mod:`~o3d_spectral.harness.runner`: the resumable evaluation loop (``o3d-spectral eval``);
* :mod:`~o3d_spectral.harness.report`: tables and plots (``o3d-spectral report``).

Needs the ``harness`` extra (pandas, matplotlib, tqdm): ``pip install 'o3d-spectral[harness]'``.
"""

from .methods import get_method, method_names, register_method, register_spectral_variant
from .metrics import SuccessCriteria, convergence_curves, instance_metrics, registration_fit
from .runner import load_results, run_eval, task_seed

__all__ = [
    "SuccessCriteria",
    "convergence_curves",
    "get_method",
    "instance_metrics",
    "load_results",
    "method_names",
    "register_method",
    "register_spectral_variant",
    "registration_fit",
    "run_eval",
    "task_seed",
]
