"""o3d-spectral: correspondence-free spectral point-cloud registration for Open3D.

The public API is flat::

    import o3d_spectral
    result = o3d_spectral.registration_spectral(source, target, voxel_size=0.008)

See ``docs/conventions.md`` for rotation, Euler-angle, spherical-harmonic and bandwidth
conventions.
"""

from .options import SpectralConvergenceCriteria, SpectralRegistrationOption
from .registration import IterationRecord, SpectralRegistrationResult, registration_spectral
from .stepper import SpectralStepper, Step

__all__ = [
    "registration_spectral",
    "SpectralRegistrationOption",
    "SpectralConvergenceCriteria",
    "SpectralRegistrationResult",
    "IterationRecord",
    "SpectralStepper",
    "Step",
]
__version__ = "0.1.0"
