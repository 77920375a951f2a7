"""Evaluation: spectral registration against Open3D's ICP, FPFH-RANSAC and FGR.

* :mod:`~o3d_spectral.harness.errors`: pose errors, plain and symmetry-aware;
* :mod:`~o3d_spectral.harness.methods`: the methods, registered by name with their settings;
* :mod:`~o3d_spectral.harness.peers`: KISS-Matcher, small_gicp (when installed), and
  FPFH-RANSAC tuned on the tuning split;
* :mod:`~o3d_spectral.harness.metrics`: per-instance errors and success;
* :mod:`~o3d_spectral.harness.runner`: the resumable evaluation loop (``o3d-spectral eval``);
* :mod:`~o3d_spectral.harness.selection`: which instances run (limit, sample, shards);
* :mod:`~o3d_spectral.harness.executors`: where they run (process pool, Dask cluster);
* :mod:`~o3d_spectral.harness.records`: what a run folder holds (sessions, results);
* :mod:`~o3d_spectral.harness.tables`, :mod:`~o3d_spectral.harness.writers`,
  :mod:`~o3d_spectral.harness.figures`: result tables, their Markdown and LaTeX, plots;
* :mod:`~o3d_spectral.harness.report`: the report of a run (``o3d-spectral report``);
* :mod:`~o3d_spectral.harness.bop`, :mod:`~o3d_spectral.harness.bop_write`,
  :mod:`~o3d_spectral.harness.pose_metrics`: datasets in the BOP layout and BOP's
  metrics (VSD, MSSD, MSPD, AR); :mod:`~o3d_spectral.harness.pairs`: scan pairs in the
  3DMatch layout; :mod:`~o3d_spectral.harness.sets`: the instance sets ``eval`` runs.

The loop, tables and plots need the ``harness`` extra (pandas, matplotlib, tqdm):
``pip install 'o3d-spectral[harness]'``; Dask clusters the ``cluster`` extra, the peers the
``peers`` extra. The names below are imported from their modules on first access, so
that importing one module does not import them all. ``Symmetry`` and ``model_symmetry``
live with the models (:mod:`~o3d_spectral.synthetic.symmetry`), which the scene generator
and the pose errors both use.
"""

from o3d_spectral.common.lazy import lazy_attributes, lazy_dir

__all__ = [
    "BopSet",
    "PairSet",
    "SuccessCriteria",
    "Symmetry",
    "convergence_curves",
    "get_method",
    "instance_metrics",
    "load_results",
    "method_names",
    "method_settings",
    "model_symmetry",
    "register_method",
    "register_spectral_variant",
    "registration_fit",
    "rotation_error",
    "run_eval",
    "symmetric_rotation_error",
    "symmetric_translation_error",
    "task_seed",
    "translation_error",
]

__getattr__ = lazy_attributes(
    __name__,
    {
        "BopSet": "bop",
        "PairSet": "pairs",
        "SuccessCriteria": "metrics",
        "Symmetry": "..synthetic.symmetry",
        "convergence_curves": "metrics",
        "get_method": "methods",
        "instance_metrics": "metrics",
        "load_results": "records",
        "method_names": "methods",
        "method_settings": "methods",
        "model_symmetry": "..synthetic.symmetry",
        "register_method": "methods",
        "register_spectral_variant": "methods",
        "registration_fit": "metrics",
        "rotation_error": "errors",
        "run_eval": "runner",
        "symmetric_rotation_error": "errors",
        "symmetric_translation_error": "errors",
        "task_seed": "runner",
        "translation_error": "errors",
    },
)
__dir__ = lazy_dir(globals(), __all__)
