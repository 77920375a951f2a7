"""o3d-spectral: correspondence-free spectral point-cloud registration for Open3D.

The public API is flat, one call per algorithm, shaped like Open3D's::

    import o3d_spectral
    # unknown pose: search all rotations (like registration_fgr_based_on_feature_matching)
    result = o3d_spectral.registration_spectral_global(source, target, voxel_size=0.008)
    # from an initial guess: the paper's control law (like registration_icp)
    result = o3d_spectral.registration_spectral(source, target, 0.008, init)

One model against many targets: :func:`prepare` it once and pass the
:class:`PreparedSource` as the source; many sources against one target:
:func:`prepare_target`, the :class:`PreparedTarget` as the target. Settings:
:class:`SpectralRegistrationOption` (representation and law), :class:`GlobalSearchOption`,
:class:`RefinementOption`, :class:`CloudOption`, :class:`SpectralConvergenceCriteria`.
Repeated calls against one
fixed cloud (visual servoing): :class:`SpectralStepper`. A voxel size for two clouds:
:func:`suggest_voxel_size`. See ``docs/architecture.md``
for the modules and ``docs/conventions.md`` for rotation, Euler-angle, spherical-harmonic
and bandwidth conventions.
"""

import logging as _logging
from typing import TYPE_CHECKING

from .common.lazy import lazy_attributes, lazy_dir

if TYPE_CHECKING:  # the names below, for type checkers; imported on first access at run time
    from .law.loop import IterationRecord
    from .law.prepared import PreparedSource, prepare
    from .law.prepared_target import PreparedTarget, prepare_target
    from .law.stepper import Evaluation, MovingCloud, SpectralStepper
    from .multiway.options import MultiwayOption, MultiwayResult, PairwiseRecord
    from .multiway.registration import registration_multiway
    from .options import (
        CloudOption,
        RefinementOption,
        SpectralConvergenceCriteria,
        SpectralRegistrationOption,
    )
    from .registration import registration_spectral, registration_spectral_global
    from .result import SpectralRegistrationResult
    from .search.options import GlobalSearchOption
    from .voxel.by_trial import VoxelTrial, voxel_trial
    from .voxel.suggestion import suggest_voxel_size

__all__ = [
    "registration_spectral",
    "registration_spectral_global",
    "registration_multiway",
    "prepare",
    "prepare_target",
    "suggest_voxel_size",
    "voxel_trial",
    "VoxelTrial",
    "PreparedSource",
    "PreparedTarget",
    "SpectralRegistrationOption",
    "GlobalSearchOption",
    "RefinementOption",
    "CloudOption",
    "SpectralConvergenceCriteria",
    "SpectralRegistrationResult",
    "MultiwayOption",
    "MultiwayResult",
    "PairwiseRecord",
    "IterationRecord",
    "SpectralStepper",
    "MovingCloud",
    "Evaluation",
]

# Imported on first access, so that a tool using only a subpackage (``o3d-spectral report``
# reads tables: pandas and matplotlib) does not wait seconds for Open3D.
__getattr__ = lazy_attributes(
    __name__,
    {
        "registration_spectral": "registration",
        "registration_spectral_global": "registration",
        "registration_multiway": "multiway.registration",
        "MultiwayOption": "multiway.options",
        "MultiwayResult": "multiway.options",
        "PairwiseRecord": "multiway.options",
        "prepare": "law.prepared",
        "prepare_target": "law.prepared_target",
        "PreparedTarget": "law.prepared_target",
        "suggest_voxel_size": "voxel.suggestion",
        "voxel_trial": "voxel.by_trial",
        "VoxelTrial": "voxel.by_trial",
        "PreparedSource": "law.prepared",
        "SpectralRegistrationResult": "result",
        "SpectralRegistrationOption": "options",
        "GlobalSearchOption": "search.options",
        "RefinementOption": "options",
        "CloudOption": "options",
        "SpectralConvergenceCriteria": "options",
        "IterationRecord": "law.loop",
        "SpectralStepper": "law.stepper",
        "MovingCloud": "law.stepper",
        "Evaluation": "law.stepper",
        "__version__": "_version",  # importlib.metadata takes longer than the rest
    },
)
__dir__ = lazy_dir(globals(), [*__all__, "__version__"])

# Library convention: the package logs to the "o3d_spectral" logger and prints nothing
# unless the application configures logging (the CLI does).
_logging.getLogger(__name__).addHandler(_logging.NullHandler())
