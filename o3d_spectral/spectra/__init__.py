"""The two representations, pure maths: voxel grids and their phase correlation, Extended
Gaussian Images in spherical harmonics and their correlation over SO(3).

* :mod:`~o3d_spectral.spectra.grid`, :mod:`~o3d_spectral.spectra.fft`,
  :mod:`~o3d_spectral.spectra.kernels`, :mod:`~o3d_spectral.spectra.translation`,
  :mod:`~o3d_spectral.spectra.target_grid`: voxel grids, planned FFTs, compiled loops,
  phase correlation, the fixed cloud's grid;
* :mod:`~o3d_spectral.spectra.harmonics`, :mod:`~o3d_spectral.spectra.egi`,
  :mod:`~o3d_spectral.spectra.wigner`, :mod:`~o3d_spectral.spectra.rotation`,
  :mod:`~o3d_spectral.spectra.so3fft`, :mod:`~o3d_spectral.spectra.shells`: spherical
  harmonics, EGIs, Wigner matrices, the rotation correlation and its derivatives, over
  all of SO(3), and on the grids' spherical shells;
* :mod:`~o3d_spectral.spectra.so3`: rotations and rigid motions.

Imports only its own modules, :mod:`o3d_spectral.io` and the package's private helpers
(``tests/test_layers.py``).
"""
