"""A voxel size for two clouds, from their point spacing and extent.

The method reads both clouds at one voxel size (:func:`o3d_spectral.registration_spectral_global`),
and the size has to suit both:

* **coarse enough for the sparser cloud**: every voxel of its surface must hold a point,
  or its voxel grid is full of holes the other cloud's is not. A surface sampled at a
  spacing ``s`` (the side of the square of surface each point stands for) holds
  ``(v / s)^2`` points per voxel face: the size is at least :data:`SPACINGS` times the
  sparser cloud's spacing (normals estimated over 2.5 voxels then have about 20
  neighbours);
* **no finer than useful for the smaller cloud**: the overlap is at most the smaller
  cloud, and it must span enough voxels for its shape to tell rotations apart; beyond
  that a finer grid costs time (the grids grow as the cube) and does not register
  better. The size is at least the smaller cloud's diameter over :data:`VOXELS_ACROSS`;
* **coarse enough for the larger cloud's grid**: the fixed cloud's grid covers all of it
  (a whole scene), and the moving cloud is placed by phase correlation over all of it:
  on a fine grid of a whole scene, the places where clutter matches the object
  outnumber the right one (a real RGB-D frame: the object placed wrong at 4-7 mm, right
  at 8 mm, where a crop of the object registers at any size), and the FFTs grow as the
  cube. The size is at least the larger cloud's diameter over :data:`MAX_VOXELS_ACROSS`.

:func:`suggest_voxel_size` takes the largest of the three. The spacing is measured as a
surface density, not as the nearest neighbour's distance: a scanner's lines, or a model
sampled in pairs, put every point's nearest neighbour much closer than the spacing the
surface is covered at. Extents are those of the clouds without their isolated points
(flying pixels, :func:`o3d_spectral.cloud.dense_bounds`). The constants were chosen on
the synthetic suites and the real scans (``eval/voxel_advice.py`` measures the
suggestion against the sizes chosen by hand; see ``docs/results.md``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from ..io.cloud import as_arrays, dense_bounds
from ..io.rows import bounds
from ..io.units import check_same_units
from .constants import (
    MAX_TREE_POINTS,
    MAX_VOXELS_ACROSS,
    NEIGHBOURS,
    SAMPLES,
    SPACINGS,
    VOXELS_ACROSS,
)

__all__ = ["suggest_voxel_size", "spacing", "SPACINGS", "VOXELS_ACROSS", "MAX_VOXELS_ACROSS",
           "NEIGHBOURS", "SAMPLES", "MAX_TREE_POINTS"]

#: Isolated points (:func:`o3d_spectral.cloud.dense_bounds`) are found with this voxel
#: relative to the spacing.
_GAP_SPACINGS = 4.0


def spacing(points: NDArray[np.float64]) -> float:
    """The spacing (metres) at which a surface is sampled by ``points`` (N, 3): the side
    of the square of surface each point stands for, the median over up to
    :data:`SAMPLES` points of ``r_k sqrt(pi / k)``, with ``r_k`` the distance of the
    :data:`NEIGHBOURS`-th nearest neighbour (0 when the points all coincide).

    A cloud of over :data:`MAX_TREE_POINTS` points is measured on a fixed random subset
    of that many (seeded: the same cloud gives the same spacing), whose spacing is
    ``sqrt(N / M)`` times the whole cloud's.
    """
    points = np.asarray(points, dtype=np.float64)
    scale = 1.0
    if len(points) > MAX_TREE_POINTS:
        keep = np.random.default_rng(0).choice(len(points), MAX_TREE_POINTS, replace=False)
        scale = np.sqrt(MAX_TREE_POINTS / len(points))
        points = points[keep]
    k = min(NEIGHBOURS, len(points) - 1)
    if k < 1:
        return 0.0
    picked = points[np.linspace(0, len(points) - 1, min(SAMPLES, len(points))).astype(np.int64)]
    distances, _ = cKDTree(points).query(picked, k=k + 1)
    return float(scale * np.median(distances[:, k]) * np.sqrt(np.pi / k))


def _bounds(points: NDArray[np.float64], step: float) -> NDArray[np.float64]:
    """Sides (metres, shape (3,)) of the box holding ``points`` without isolated ones."""
    lower, upper = dense_bounds(points, step) if step > 0.0 else bounds(points)
    return upper - lower


def suggest_voxel_size(source: object, target: object) -> float:
    """A voxel size (metres) suited to registering ``source`` to ``target``.

    The largest of: :data:`SPACINGS` times the sparser cloud's point spacing
    (:func:`spacing`: enough points in every voxel of a surface for its normals); the
    smaller cloud's diameter over :data:`VOXELS_ACROSS` (finer grids cost more without
    telling rotations apart better); the larger cloud's diameter over
    :data:`MAX_VOXELS_ACROSS` (a whole scene's grid, over which the object is placed).
    Diameters are the diagonals of the clouds' boxes without their isolated points
    (flying pixels, :func:`o3d_spectral.cloud.dense_bounds`). The result scales with the
    clouds: clouds scaled by ``k`` get ``k`` times the size. See
    ``docs/conventions.md`` for the rule and ``docs/results.md`` for its measure.

    Parameters
    ----------
    source, target : PointCloud, tensor PointCloud or ndarray
        Clouds in metres (``open3d.geometry.PointCloud``,
        ``open3d.t.geometry.PointCloud``, or a numpy array of shape (N, 3), or (N, 6)
        with normals, which are not used), as for
        :func:`o3d_spectral.registration_spectral_global`. Neither is modified.

    Returns
    -------
    float
        Voxel edge, metres, for ``voxel_size`` of the registration calls.

    Raises
    ------
    TypeError
        For an unsupported cloud type, or an array that does not hold real numbers.
    ValueError
        For an empty cloud, NaN or infinite coordinates, an array of the wrong shape, a
        cloud whose points all coincide, each message naming the argument; or clouds whose
        extents differ by 50x or more (:func:`o3d_spectral.io.units.check_same_units`: in
        different units, or a scene to crop around the object), the message naming both.

    Examples
    --------
    >>> voxel = o3d_spectral.suggest_voxel_size(model, scan)  # doctest: +SKIP
    >>> result = o3d_spectral.registration_spectral_global(model, scan, voxel)  # doctest: +SKIP
    """
    clouds = {"source": as_arrays(source, "source").points,
              "target": as_arrays(target, "target").points}
    spacings, sides = {}, {}
    for name, points in clouds.items():
        spacings[name] = spacing(points)
        if not spacings[name] > 0.0:
            raise ValueError(f"{name}: its points all coincide (no surface to register)")
        sides[name] = _bounds(points, _GAP_SPACINGS * spacings[name])
    check_same_units(clouds["source"], clouds["target"])  # no size suits both
    densest = SPACINGS * max(spacings.values())
    diameters = sorted(float(np.linalg.norm(s)) for s in sides.values())
    return float(max(densest, diameters[0] / VOXELS_ACROSS,
                     diameters[1] / MAX_VOXELS_ACROSS))
