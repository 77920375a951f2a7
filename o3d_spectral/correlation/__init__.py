"""Batched phase correlation: many turned copies of one cloud against one fixed grid.

The global search ranks rotations by the height of the phase-correlation peak of the
turned moving cloud's voxel grid against the fixed one (paper, eqs. cross_power_spectrum
and fourier_shift_solution): thousands of the same small pipeline, each a turn and a
splat, a forward 3D FFT, the whitened cross-power against one fixed spectrum, an inverse
FFT and a peak. This layer runs that pipeline over stacks of rotations on an array
backend:

* :mod:`~o3d_spectral.correlation.backend`: what the pipeline asks of an array library,
  answered on the CPU by one compiled loop outside the GIL (every core);
* :mod:`~o3d_spectral.correlation.numpy_api`: the same answered by any library with
  NumPy's API (NumPy itself, CuPy on a GPU) over whole stacks;
* :mod:`~o3d_spectral.correlation.batched`: :class:`BatchedCorrelation`, the fixed
  spectrum held on the backend and the peaks of a stack of rotations, and
  :class:`TurnedCloud`, the moving cloud as the pipeline turns it;
* :mod:`~o3d_spectral.correlation.device`: the backend for a device named in Open3D's
  manner (``"CPU:0"``, ``"CUDA:0"``).

Free of Open3D: it runs where only NumPy (and CuPy) are installed. Imports only its own
modules, :mod:`o3d_spectral.spectra` and the package's helpers (``tests/test_layers.py``).
"""

from .backend import Backend, CompiledBackend, Fixed, Found, array_backend
from .batched import BatchedCorrelation, Peaks, TurnedCloud
from .device import Device, device_backend, parse_device
from .numpy_api import ArrayBackend

__all__ = [
    "ArrayBackend", "Backend", "BatchedCorrelation", "CompiledBackend", "Device", "Fixed",
    "Found", "Peaks", "TurnedCloud", "array_backend", "device_backend", "parse_device",
]
