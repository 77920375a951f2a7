"""Numeric constants of the spectral maths (``o3d_spectral.spectra``), by the module using them."""

# -- spectra.fft: the FFTs -----------------------------------------------------------------

#: Plans kept per thread (the least recently used beyond this are dropped).
CACHED_PLANS = 8


# -- spectra.correlation_loop: the compiled correlation's workspaces ----------------------

#: Workspace sizes a thread keeps: one search correlates on a few grids (the dense
#: search's coarse and fine ones, the placements', the climbs' windows), each at one
#: batch size.
WORKSPACES = 6
#: Bytes of workspaces a thread keeps between calls (beyond them the least recently used
#: are dropped, never the one in use): the search's threads outlive a call, and on many
#: cores a scene's whole-grid workspaces (tens of MB each) would otherwise stay with
#: every thread.
WORKSPACE_BYTES = 2**28


# -- spectra.harmonic_kernels: the compiled sum of harmonics -------------------------------

#: Directions whose harmonics :func:`harmonic_sums` carries through the recurrence
#: together: each step is then a short loop over them that the compiler vectorises.
HARMONIC_BLOCK = 64


# -- spectra.shells: rotations from the shells ---------------------------------------------

#: Voxels along each side of the grid whose spectrum is sampled.
SHELL_GRID = 64
#: Voxels the object's largest extent spans in that grid (the rest is zero padding,
#: which samples the spectrum more finely).
SHELL_SPAN = 20
#: Bandwidth of each shell's spherical-harmonic expansion (degrees below it).
SHELL_BANDWIDTH = 24
#: Radial step between shells, in frequency samples.
SHELL_STEP = 2


# -- spectra.translation: the phase correlation -------------------------------------------

#: Cross-power terms under this share of the largest (the zero frequency's) are not
#: whitened: they carry no phase, only rounding (single precision's is about 6e-8).
WHITENING_EPS = 1e-6


# -- spectra.target_grid: the fixed cloud's grid -------------------------------------------

#: Fixed-grid spectra kept at most (servoing meets many shapes: keep the last few).
CACHED_SPECTRA = 8
#: Coarser grids kept at most (:meth:`TargetGrid.coarsened`; a servo run meets many
#: captures: keep the last few).
CACHED_COARSE_GRIDS = 4
#: A fixed cloud whose radius exceeds a moving one's by this factor holds more than the
#: moving cloud: a scene (:meth:`TargetGrid.holds_more`).
SCENE_RATIO = 1.5
#: Voxel of the grid candidates are first placed on between two views, in voxels (an
#: eighth of the FFT; :meth:`TargetGrid.coarsened`).
COARSE_FACTOR = 2.0
