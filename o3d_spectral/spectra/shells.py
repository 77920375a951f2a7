"""Rotation from the magnitude of the voxel grids' Fourier transforms, on spherical shells.

The magnitude ``|V(k)|`` of a voxel grid's 3D Fourier transform does not change when the
cloud is translated (a shift only turns the phase, eq. fourier_shift), and turns with the
cloud: if ``target = R source + t`` then ``|V_t(k)| = |V_s(R^T k)|``. Sampled on spheres
``|k| = rho`` of the frequency space, each shell is a function on the sphere, and the
rotation correlation of every shell at once (:func:`o3d_spectral.spectra.so3fft.correlation_grid`
with stacked coefficients) gives rotation candidates over all of SO(3) with no
translation known, as the EGI does (Buelow and Birk, "Spectral 6DOF registration of
noisy 3D range data with partial overlap", IEEE PAMI 2013).

Unlike the EGI, the shells hold the shape itself, not only the directions of its
normals, so two views of one object that each miss what the other sees still share
most of their spectrum: the candidates
:func:`o3d_spectral.search.candidates.shell_candidates` adds for two single views, where
the EGIs of the two views differ by what each sensor sees.

The grid is sized to the clouds, not to the caller's voxel: ``SHELL_GRID`` voxels a side,
the object spanning ``SHELL_SPAN`` of them, so that the spectrum is sampled alike
whatever the input's resolution.
"""

from __future__ import annotations

import numpy as np
import scipy.fft
from numpy.typing import ArrayLike, NDArray
from scipy.ndimage import map_coordinates

from ..io.rows import largest_side
from .constants import SHELL_BANDWIDTH, SHELL_GRID, SHELL_SPAN, SHELL_STEP
from .egi import grid_points
from .harmonics import sht

__all__ = ["SHELL_GRID", "SHELL_SPAN", "SHELL_BANDWIDTH", "shell_voxel", "shell_coefficients",
           "magnitude_spectrum"]


def shell_voxel(*points: ArrayLike) -> float:
    """The shells' voxel edge (metres): the largest extent of any of the point sets
    (each (N, 3), metres) over ``SHELL_SPAN``."""
    return max(largest_side(np.asarray(p, dtype=np.float64)) for p in points) / SHELL_SPAN


def _magnitude(points: NDArray[np.float64], voxel: float) -> NDArray[np.float64]:
    """``|V(k)|`` of the binary occupancy grid of ``points`` about their centroid,
    zero frequency at the centre, shape ``(SHELL_GRID,) * 3``."""
    n = SHELL_GRID
    index = np.floor((points - points.mean(axis=0)) / voxel).astype(np.int64) + n // 2
    index = index[np.all((index >= 0) & (index < n), axis=1)]
    grid = np.zeros((n, n, n))
    grid[tuple(index.T)] = 1.0
    return magnitude_spectrum(grid)


def magnitude_spectrum(grid: NDArray[np.float64]) -> NDArray[np.float64]:
    """``|V(k)|`` of a real cubic ``grid`` (n, n, n), n even, zero frequency at the centre
    (``abs(fftshift(fftn(grid)))``), from the real FFT's half spectrum: the spectrum of a
    real grid is Hermitian, ``V(-k) = conj(V(k))``, so ``|V(-k)| = |V(k)|`` gives the other
    half (a third of the full complex transform's time)."""
    n = grid.shape[0]
    half = np.abs(scipy.fft.rfftn(grid))  # k_z in [0, n/2]
    negated = -np.arange(n) % n
    whole = np.empty((n, n, n))
    whole[:, :, : n // 2 + 1] = half
    whole[:, :, n // 2 + 1 :] = half[np.ix_(negated, negated, np.arange(n // 2 - 1, 0, -1))]
    return np.fft.fftshift(whole)


def shell_coefficients(points: ArrayLike, voxel: float) -> NDArray[np.float64]:
    """Real spherical-harmonic coefficients of ``|V(k)|`` on each shell, degree 0 dropped
    and each shell scaled to unit norm (every shell weighs alike in the correlation).

    Parameters
    ----------
    points : array_like, shape (N, 3)
        Metres.
    voxel : float
        Voxel edge of the occupancy grid, metres (:func:`shell_voxel`, the same for both
        clouds).

    Returns
    -------
    ndarray, shape (S, SHELL_BANDWIDTH, 2 SHELL_BANDWIDTH - 1)
        One expansion per shell radius ``2, 4, ...`` frequency samples, below Nyquist.
    """
    magnitude = _magnitude(np.asarray(points, dtype=np.float64).reshape(-1, 3), voxel)
    B, centre = SHELL_BANDWIDTH, SHELL_GRID // 2
    directions = grid_points(B).reshape(-1, 3)
    shells = []
    for radius in range(SHELL_STEP, centre - 2, SHELL_STEP):
        samples = map_coordinates(magnitude, (directions * radius + centre).T, order=1)
        F = sht(samples.reshape(2 * B, 2 * B), B)
        F[0] = 0.0
        norm = np.linalg.norm(F)
        shells.append(F / norm if norm > 0 else F)
    return np.stack(shells)
