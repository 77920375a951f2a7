"""Extended Gaussian Images: the distribution of surface normals on the sphere (paper, eq. egi).

The EGI does not change when a cloud is translated, which is what decouples rotation
from translation. Two ways to get its spherical-harmonic coefficients:

- ``binned=True``: the paper's histogram of normals on the ``2B x 2B`` grid
  (:func:`histogram`), turned into a density and transformed by
  :func:`~o3d_spectral.spectra.harmonics.sht`;
- ``binned=False`` (default): the exact coefficients of the normals themselves
  (:func:`~o3d_spectral.spectra.harmonics.project`), which the histogram approximates by moving
  each normal to its bin's centre. Rotating the normals then multiplies the coefficients
  by ``U^l(R)`` exactly, so the rotation correlation has no binning error.

Either way the coefficients are then smoothed (a heat kernel of angular width ``sigma``,
which stands for the normals' noise and keeps the correlation free of ringing) and may be
normalised (:func:`normalise`) so that one gain fits every cloud.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..io.rows import lengths
from .harmonics import grid_angles, project, quadrature_weights, real_sph_harm, sht

__all__ = [
    "histogram", "coefficients", "harmonics_table", "smooth", "normalise", "grid_points",
    "facing",
]


def _unit(normals: ArrayLike) -> NDArray[np.float64]:
    n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    return n / lengths(n)[:, None]


def histogram(
    normals: ArrayLike, bandwidth: int, weights: ArrayLike | None = None
) -> NDArray[np.float64]:
    """Histogram of unit normals on the paper's ``2B x 2B`` grid (eq. egi).

    Bin ``(j, k)`` is centred on ``(theta_j, phi_k) = (pi (2j+1) / 4B, pi k / B)`` and spans
    ``pi / 2B`` in colatitude and ``pi / B`` in longitude.

    Parameters
    ----------
    normals : array_like, shape (N, 3)
    bandwidth : int
    weights : array_like, shape (N,), optional
        Mass per normal (1 when omitted: counts, as in the paper).

    Returns
    -------
    ndarray, shape (2B, 2B)
        ``[j, k]``: total weight of the normals in bin ``(theta_j, phi_k)``.
    """
    B = int(bandwidth)
    n = _unit(normals)
    theta = np.arccos(np.clip(n[:, 2], -1.0, 1.0))
    phi = np.arctan2(n[:, 1], n[:, 0])
    j = np.clip(np.floor(theta / (np.pi / (2 * B))).astype(np.int64), 0, 2 * B - 1)
    k = np.round(phi / (np.pi / B)).astype(np.int64) % (2 * B)
    w = np.ones(len(n)) if weights is None else np.asarray(weights, dtype=np.float64)
    return np.bincount(j * 2 * B + k, weights=w, minlength=4 * B * B).reshape(2 * B, 2 * B)


def smooth(coefficients: ArrayLike, sigma: float) -> NDArray[np.float64]:
    """Heat-kernel smoothing on the sphere: degree ``l`` scaled by ``exp(-l(l+1) sigma^2 / 2)``.

    Parameters
    ----------
    coefficients : array_like, shape (B, 2B - 1)
    sigma : float
        Angular width of the kernel, radians (0 leaves the coefficients unchanged).

    Returns
    -------
    ndarray, shape (B, 2B - 1)
    """
    F = np.asarray(coefficients, dtype=np.float64)
    l = np.arange(F.shape[0])  # noqa: E741
    return F * np.exp(-0.5 * l * (l + 1) * sigma**2)[:, None]


def coefficients(
    normals: ArrayLike,
    bandwidth: int,
    *,
    weights: ArrayLike | None = None,
    binned: bool = False,
    sigma: float = 0.0,
    two_sided: bool = False,
) -> NDArray[np.float64]:
    """Spherical-harmonic coefficients ``F^l`` of the EGI (eq. real_fourier_transform_fr).

    Parameters
    ----------
    normals : array_like, shape (N, 3)
        Surface normals (any length; normalised here).
    bandwidth : int
        ``B``: degrees ``0 <= l < B``.
    weights : array_like, shape (N,), optional
        Mass per normal (e.g. surface area); 1 when omitted.
    binned : bool
        Use the paper's ``2B x 2B`` histogram (True) or the exact projection (False).
    sigma : float
        Heat-kernel smoothing width, radians.
    two_sided : bool
        Count each normal both ways, ``n`` and ``-n`` with half its weight each (the EGI
        of a surface whose sides are not told apart): as ``S_lm(-n) = (-1)^l S_lm(n)``,
        the odd degrees vanish and the even ones are unchanged.

    Returns
    -------
    ndarray, shape (B, 2B - 1)
        The EGI's coefficients; degree 0 is the total weight over ``sqrt(4 pi)``.
    """
    if binned:
        counts = histogram(normals, bandwidth, weights)
        density = counts / quadrature_weights(bandwidth)[:, None]  # mass per steradian
        F = sht(density, bandwidth)
    else:
        F = project(_unit(normals), weights, bandwidth)
    if two_sided:
        F[1::2] = 0.0
    return smooth(F, sigma) if sigma > 0 else F


def harmonics_table(normals: ArrayLike, bandwidth: int) -> NDArray[np.float64]:
    """Real spherical harmonics at each normal, flattened: ``[i, l * (2B - 1) + m + B - 1]
    = S_lm(n_i)``, shape (N, B (2B - 1)).

    For a cloud whose EGI is built again and again from subsets of its normals with
    changing weights (the visible part of a moving cloud at each pose), the coefficients
    of a subset ``k`` with weights ``w`` are ``(w @ table[k]).reshape(B, 2B - 1)``,
    :func:`coefficients` without recomputing the harmonics. Zero normals give rows of
    no meaning: leave them out of every subset.
    """
    n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    length = np.maximum(lengths(n), 1e-300)
    theta = np.arccos(np.clip(n[:, 2] / length, -1.0, 1.0))
    phi = np.arctan2(n[:, 1], n[:, 0])
    return real_sph_harm(bandwidth, theta, phi).reshape(len(n), -1)


def normalise(coefficients: ArrayLike) -> NDArray[np.float64]:
    """Drop degree 0 (a constant, blind to rotation) and scale to unit L2 norm.

    Makes the rotation correlation independent of the number of points, so that one
    rotation gain fits every cloud.

    Parameters
    ----------
    coefficients : array_like, shape (B, 2B - 1)

    Returns
    -------
    ndarray, shape (B, 2B - 1)

    Raises
    ------
    ValueError
        If nothing is left (an isotropic or empty EGI carries no rotation information).
    """
    F = np.array(coefficients, dtype=np.float64)
    F[0] = 0.0
    norm = np.linalg.norm(F)
    if not np.isfinite(norm) or norm < 1e-12:
        raise ValueError("the normals' distribution carries no rotation information")
    return F / norm


def grid_points(bandwidth: int) -> NDArray[np.float64]:
    """Unit vectors at the ``2B x 2B`` grid's sample points, shape (2B, 2B, 3)."""
    theta, phi = grid_angles(bandwidth)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    return np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1)


def facing(direction: ArrayLike) -> Callable[[NDArray[np.float64]], NDArray[np.float64]]:
    """The weight with which a sensor in ``direction`` samples a surface of normal ``n``:
    the cosine of incidence ``max(0, n . d)`` (0 for surfaces facing away).

    Parameters
    ----------
    direction : array_like, shape (3,)
        From the surface towards the sensor (any length).

    Returns
    -------
    callable
        Unit vectors (..., 3) to weights (...).
    """
    d = np.asarray(direction, dtype=np.float64).reshape(3)
    norm = np.linalg.norm(d)
    if not (np.isfinite(norm) and norm > 0):
        raise ValueError(f"direction must be a finite non-zero vector, got {direction}")
    d = d / norm

    def weight(normals: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.maximum(np.asarray(normals) @ d, 0.0)

    return weight
