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

from ._lazy import lazy_attributes, lazy_dir

if TYPE_CHECKING:  # the names below, for type checkers; imported on first access at run time
    from .law import IterationRecord
    from .multiway import registration_multiway
    from .multiway_options import MultiwayOption, MultiwayResult, PairwiseRecord
    from .options import (
        CloudOption,
        RefinementOption,
        SpectralConvergenceCriteria,
        SpectralRegistrationOption,
    )
    from .prepared import PreparedSource, prepare
    from .prepared_target import PreparedTarget, prepare_target
    from .registration import registration_spectral, registration_spectral_global
    from .result import SpectralRegistrationResult
    from .search_options import GlobalSearchOption
    from .stepper import Evaluation, MovingCloud, SpectralStepper
    from .voxel import suggest_voxel_size
    from .voxel_by_trial import VoxelTrial, voxel_trial

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
        "registration_multiway": "multiway",
        "MultiwayOption": "multiway_options",
        "MultiwayResult": "multiway_options",
        "PairwiseRecord": "multiway_options",
        "prepare": "prepared",
        "prepare_target": "prepared_target",
        "PreparedTarget": "prepared_target",
        "suggest_voxel_size": "voxel",
        "voxel_trial": "voxel_by_trial",
        "VoxelTrial": "voxel_by_trial",
        "PreparedSource": "prepared",
        "SpectralRegistrationResult": "result",
        "SpectralRegistrationOption": "options",
        "GlobalSearchOption": "search_options",
        "RefinementOption": "options",
        "CloudOption": "options",
        "SpectralConvergenceCriteria": "options",
        "IterationRecord": "law",
        "SpectralStepper": "stepper",
        "MovingCloud": "stepper",
        "Evaluation": "stepper",
        "__version__": "_version",  # importlib.metadata takes longer than the rest
    },
)
__dir__ = lazy_dir(globals(), [*__all__, "__version__"])

# Library convention: the package logs to the "o3d_spectral" logger and prints nothing
# unless the application configures logging (the CLI does).
_logging.getLogger(__name__).addHandler(_logging.NullHandler())
