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

# Kept at the end, beside the lines that use them (the imports above are the public API).
import logging as _logging  # noqa: E402
from importlib import metadata as _metadata  # noqa: E402

try:  # the installed distribution's version, so it cannot drift from pyproject.toml
    __version__ = _metadata.version("o3d-spectral")
except _metadata.PackageNotFoundError:  # not installed: a bare source tree on sys.path
    __version__ = "0+unknown"

# Library convention: the package logs to the "o3d_spectral" logger and prints nothing
# unless the application configures logging (the CLI does).
_logging.getLogger(__name__).addHandler(_logging.NullHandler())
