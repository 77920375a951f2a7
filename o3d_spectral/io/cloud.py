"""Input clouds: conversion from Open3D and numpy types, validation, down-sampling, normals.

Every public entry point passes its clouds through :func:`as_arrays` (which copies, so the
caller's cloud is never modified) and :func:`prepare`.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import numpy as np
import open3d as o3d
from numpy.typing import ArrayLike, NDArray

from ..common.checks import real_array
from .constants import ISOLATED_GAP, ISOLATED_SHARE, MIN_POINTS
from .normals import faces, orient, view_direction
from .rows import bounds, every, lengths
from .signs import SIGN_DISAGREEMENT, THIN_WALLS, neighbour_signs

__all__ = [
    "CloudArrays", "CloudReading", "PreparedCloud", "as_arrays", "to_legacy", "prepare",
    "MIN_POINTS", "extent", "dense_bounds",
]


logger = logging.getLogger(__name__)

CloudLike = "o3d.geometry.PointCloud | o3d.t.geometry.PointCloud | numpy.ndarray"


@dataclass(frozen=True)
class CloudArrays:
    """A cloud as arrays (always copies of the input).

    Attributes
    ----------
    points : ndarray, shape (N, 3)
        Metres.
    normals : ndarray, shape (N, 3) or None
        As given (not necessarily unit length), or None when the input had none.
    """

    points: NDArray[np.float64]
    normals: NDArray[np.float64] | None


def as_arrays(cloud: object, name: str = "cloud") -> CloudArrays:
    """Copy a cloud into float64 arrays and check it.

    Parameters
    ----------
    cloud : open3d.geometry.PointCloud, open3d.t.geometry.PointCloud, ndarray or CloudArrays
        A numpy array must have shape (N, 3) (points) or (N, 6) (points, then normals);
        a CloudArrays is returned as it is.
    name : str
        Argument name used in error messages.

    Raises
    ------
    TypeError
        For an unsupported type.
    ValueError
        For under :data:`MIN_POINTS` points (an empty cloud: how to sample a mesh), a wrong
        array shape, non-finite coordinates or normals, or normals all zero.
    """
    if isinstance(cloud, CloudArrays):  # already converted and checked
        return cloud
    if isinstance(cloud, o3d.geometry.PointCloud):
        points = np.asarray(cloud.points, dtype=np.float64).copy()
        normals = np.asarray(cloud.normals, dtype=np.float64).copy()
        normals = normals if cloud.has_normals() else None
    elif isinstance(cloud, o3d.t.geometry.PointCloud):
        if "positions" not in cloud.point:
            raise ValueError(f"{name}: the tensor point cloud has no 'positions'")
        points = real_array(f"{name} positions", cloud.point.positions).reshape(-1, 3)
        normals = (real_array(f"{name} normals", cloud.point.normals).reshape(-1, 3)
                   if "normals" in cloud.point else None)
    elif isinstance(cloud, np.ndarray | list | tuple):
        array = real_array(name, cloud)  # a copy; bool, complex or text refused
        if array.ndim != 2 or array.shape[1] not in (3, 6):
            raise ValueError(f"{name}: a numpy cloud must have shape (N, 3) or (N, 6), "
                             f"got {array.shape}")
        points = np.ascontiguousarray(array[:, :3])
        normals = np.ascontiguousarray(array[:, 3:]) if array.shape[1] == 6 else None
    else:
        raise TypeError(f"{name}: expected {CloudLike}, got {type(cloud).__name__}")
    if len(points) < MIN_POINTS:  # none: a mesh file read as a cloud; few: its vertices?
        count = "is empty" if len(points) == 0 else f"has {len(points)} points"
        raise ValueError(f"{name} {count}; the method needs at least {MIN_POINTS}: a denser "
                         "cloud (of a mesh, its surface sampled, not its vertices nor "
                         "read_point_cloud: read_triangle_mesh(path).sample_points_uniformly(n))")
    bad = ~every(np.isfinite(points))
    if bad.any():
        raise ValueError(
            f"{name} has {int(bad.sum())} points with NaN or infinite coordinates; "
            "remove them first (e.g. PointCloud.remove_non_finite_points())"
        )
    if normals is not None:
        if normals.shape != points.shape:
            raise ValueError(f"{name}: {len(normals)} normals for {len(points)} points")
        bad = ~every(np.isfinite(normals))
        if bad.any():
            raise ValueError(f"{name} has {int(bad.sum())} normals with NaN or infinite entries")
        if not np.any(lengths(normals) > 1e-6):  # as prepare uses them
            raise ValueError(f"{name}: its normals are all zero; give unit ones, or none")
    return CloudArrays(points, normals)


def to_legacy(arrays: CloudArrays) -> o3d.geometry.PointCloud:
    """A new legacy Open3D cloud holding the arrays (normals if any)."""
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(arrays.points))
    if arrays.normals is not None:
        cloud.normals = o3d.utility.Vector3dVector(arrays.normals)
    return cloud


def extent(points: NDArray[np.float64]) -> tuple[NDArray[np.float64], float]:
    """Centroid (metres, shape (3,)) of ``points`` (N, 3) and the largest distance of a
    point from it (metres): the ball that holds the cloud under any rotation about it."""
    centroid = points.mean(axis=0)
    return centroid, float(np.max(lengths(points - centroid)))


def dense_bounds(
    points: ArrayLike, voxel_size: float, *, gap: float = ISOLATED_GAP,
    share: float = ISOLATED_SHARE,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Bounds (metres, shape (3,) each) of a cloud without its isolated points.

    Along each axis, the points beyond the outermost gap wider than ``gap`` voxels among
    the ``share`` of points nearest either end are isolated: stray returns and flying
    pixels far from the surfaces, which would otherwise size the voxel grids (20 points
    2 m away from a 20 cm object make its grid a thousand times larger). Gaps inside the
    cloud's bulk never cut it: at most ``share`` of the points go at each end.

    Parameters
    ----------
    points : array_like, shape (N, 3)
        Metres.
    voxel_size : float
        Metres.
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    lower, upper = bounds(p)
    k = int(share * len(p))
    if k == 0:
        return lower, upper
    for axis in range(3):
        parted = np.partition(p[:, axis], (k, len(p) - k - 1))  # both ends in one pass
        ends = np.sort(parted[: k + 1])
        wide = np.flatnonzero(np.diff(ends) > gap * voxel_size)
        if len(wide):
            lower[axis] = ends[wide[-1] + 1]
        ends = np.sort(parted[len(p) - k - 1 :])
        wide = np.flatnonzero(np.diff(ends) > gap * voxel_size)
        if len(wide):
            upper[axis] = ends[wide[0]]
    return lower, upper


def _without_isolated(arrays: CloudArrays, voxel_size: float, name: str) -> CloudArrays:
    """``arrays`` without the points outside :func:`dense_bounds` (logged)."""
    lower, upper = dense_bounds(arrays.points, voxel_size)
    keep = every((arrays.points >= lower) & (arrays.points <= upper))
    if keep.all():
        return arrays
    logger.info("%s: %d isolated points (beyond a %g-voxel gap) left out", name,
                int((~keep).sum()), ISOLATED_GAP)
    normals = None if arrays.normals is None else arrays.normals[keep]
    return CloudArrays(arrays.points[keep], normals)


@dataclass(frozen=True)
class CloudReading:
    """How :func:`prepare` read a cloud (reported in the registration result).

    Attributes
    ----------
    normals_from : {"given", "re-oriented", "estimated"}
        The caller's normals, as given or with their signs chosen again (neighbours
        disagreed, :func:`o3d_spectral.io.signs.sign_disagreement`), or estimated.
    orientation : {"camera", "sensor frame", "hemisphere", "surface"} or None
        The rule that chose their signs (:func:`o3d_spectral.io.normals.orient`); None for
        normals used as given.
    view : ndarray, shape (3,), or None
        Unit direction towards the sensor when the normals say the cloud is a single
        view, in the cloud's frame: towards the frame's origin when its normals face it
        (a view in its sensor's frame), else :func:`o3d_spectral.io.normals.view_direction`;
        None otherwise (always for a two-sided cloud).
    sign_disagreement : float or None
        For given normals: the share of neighbours whose normals point to opposite sides
        (:func:`o3d_spectral.io.signs.sign_disagreement`); None when not measured (estimated
        normals, or given normals that face the sensor).
    flatness : float
        Length of the mean unit normal: 1 when all normals are alike (a plane, whose
        EGI leaves the rotation about it free), near 0 for a closed surface.
    two_sided : bool
        The given normals disagree between neighbours because they point away from each
        other (:func:`o3d_spectral.io.signs.back_to_back`): the two faces of walls thinner
        than the points' spacing (a bowl, a mug), which at the voxel scale are one sheet
        a sensor may see from either side. Their signs are then not used: the EGI holds
        each normal both ways (:func:`o3d_spectral.spectra.egi.coefficients`, ``two_sided``) and
        a sensor sees every surface, turned to face it
        (:meth:`o3d_spectral.SpectralStepper.visible`).
    """

    normals_from: str = "given"
    orientation: str | None = None
    view: NDArray[np.float64] | None = None
    sign_disagreement: float | None = None
    flatness: float = 0.0
    two_sided: bool = False

    def turned(self, rotation: NDArray[np.float64]) -> CloudReading:
        """The same reading of the cloud turned by ``rotation`` (3, 3)."""
        view = None if self.view is None else rotation @ self.view
        return replace(self, view=view)


@dataclass(frozen=True)
class PreparedCloud:
    """A cloud reduced to what the method uses.

    Attributes
    ----------
    points : ndarray, shape (M, 3)
        One point per occupied voxel of ``voxel_size`` (the voxel grid's input), metres.
    point_normals : ndarray, shape (M, 3)
        Mean normal in each voxel (unit, or zero where opposite normals cancel).
    normals : ndarray, shape (K, 3)
        Unit normals, the EGI's input (each counts once).
    normal_points : ndarray, shape (K, 3)
        Where those normals are, metres.
    reading : CloudReading
        How its normals were obtained and whether it is a single view.
    """

    points: NDArray[np.float64]
    point_normals: NDArray[np.float64]
    normals: NDArray[np.float64]
    normal_points: NDArray[np.float64]
    reading: CloudReading


def _check_shape(points: NDArray[np.float64], voxel_size: float, name: str, count: int) -> None:
    """Enough occupied voxels (of the cloud's ``count`` points), and not all on one line."""
    if len(points) < MIN_POINTS:
        raise ValueError(
            f"{name} occupies {len(points)} voxels of {voxel_size:.4g} m (its {count} points); "
            f"the method needs at least {MIN_POINTS}: use a smaller voxel_size or a denser cloud"
        )
    spread = np.linalg.svd(points - points.mean(axis=0), compute_uv=False)
    if spread[1] < 1e-3 * spread[0] or spread[1] < 0.5 * voxel_size:
        raise ValueError(f"{name} is degenerate: its points lie (nearly) on a line")


def _signs_checked(
    arrays: CloudArrays, voxel_size: float, camera_location: ArrayLike | None,
    origin: ArrayLike | None,
) -> tuple[CloudArrays, str | None, float | None, bool]:
    """Given normals as they are when their signs agree along the surface; otherwise
    with their signs chosen again by :func:`o3d_spectral.io.normals.orient`. Returned with
    the rule that chose them (None: as given, or two-sided), the share of neighbours
    that disagreed and whether the cloud is two-sided (its disagreeing neighbours back to
    back, :data:`o3d_spectral.io.signs.THIN_WALLS`: the signs are then chosen only so that
    the normals averaged per voxel do not cancel, and are not used otherwise).

    Normals that nearly all face the sensor (``camera_location``, else ``origin``) are
    signed by it, as :func:`orient` would: used as given, no neighbour search (a depth
    capture in its camera's frame; the disagreement is then None)."""
    sensor = camera_location if camera_location is not None else origin
    sensor = np.zeros(3) if sensor is None else sensor
    if faces(arrays.points, arrays.normals, sensor, share=1.0 - SIGN_DISAGREEMENT):
        return arrays, None, None, False
    disagreement, away = neighbour_signs(arrays.points, arrays.normals)
    if disagreement <= SIGN_DISAGREEMENT:
        return arrays, None, disagreement, False
    two_sided = away >= THIN_WALLS
    norms = lengths(arrays.normals)[:, None]
    unit = np.divide(arrays.normals, norms, out=np.zeros_like(arrays.normals),
                     where=norms > 1e-12)
    normals, rule = orient(arrays.points, unit, voxel_size, camera_location=camera_location,
                           origin=origin)
    oriented = CloudArrays(arrays.points, normals * norms)
    return oriented, None if two_sided else rule, disagreement, two_sided


def _view(
    points: NDArray[np.float64], normals: NDArray[np.float64], voxel_size: float,
    origin: ArrayLike | None,
) -> NDArray[np.float64] | None:
    """:attr:`CloudReading.view` of unit ``normals`` (K, 3) at ``points`` (metres)."""
    sensor = np.zeros(3) if origin is None else np.asarray(origin, dtype=np.float64)
    toward = sensor - points.mean(axis=0)
    if faces(points, normals, sensor) and np.linalg.norm(toward) > voxel_size:  # seen from there
        return toward / np.linalg.norm(toward)
    return view_direction(points, normals, voxel_size)  # a search (0.07 s on a view)


def prepare(
    arrays: CloudArrays,
    voxel_size: float,
    *,
    egi_voxel_size: float | None = None,
    max_egi_points: int = 50_000,
    normal_radius: float | None = None,
    camera_location: ArrayLike | None = None,
    origin: ArrayLike | None = None,
    name: str = "cloud",
) -> PreparedCloud:
    """Down-sample a cloud and provide unit normals, consistently oriented.

    Given normals are used point by point, unaveraged, so that the EGI of a rotated copy
    of a cloud is exactly the rotated EGI (every point counts once: down-sample a cloud
    of very uneven density first); when their signs disagree along the surface they are
    oriented again, or, when they disagree back to back (walls thinner than the points'
    spacing), the cloud is read two-sided (:attr:`CloudReading.two_sided`: signs chosen
    only for the per-voxel means, and no view). When the cloud has no normals they are
    estimated on the cloud averaged per cell of ``egi_voxel_size`` (PCA over
    ``normal_radius``, 30 neighbours at most). Either way the signs are chosen by
    :func:`o3d_spectral.io.normals.orient`: towards ``camera_location`` when given; towards
    the origin when the cloud is a depth map seen from an origin outside it (a scan in
    its sensor's frame); else consistently along the surface and outward from the
    centroid. The voxel grid's points are the cloud averaged per voxel of ``voxel_size``.

    Parameters
    ----------
    arrays : CloudArrays
    voxel_size : float
        Metres.
    egi_voxel_size : float, optional
        Metres; ``voxel_size / 4`` when omitted.
    max_egi_points : int
        Normals kept at most for the EGI (a fixed, evenly spread subset beyond that).
    normal_radius : float, optional
        Metres; ``2.5 * voxel_size`` when omitted.
    camera_location : array_like, shape (3,), optional
        Sensor position in the cloud's frame, metres.
    origin : array_like, shape (3,), optional
        Where the origin of the frame the caller gave the cloud in lies, metres (a
        scan's sensor when it is in its sensor's frame); the origin when omitted.
    name : str
        Argument name used in error and log messages.

    Returns
    -------
    PreparedCloud

    Raises
    ------
    ValueError
        When fewer than :data:`MIN_POINTS` voxels are occupied, or the points are
        (nearly) collinear.
    """
    arrays = _without_isolated(arrays, voxel_size, name)
    normals_from, rule, disagreement, two_sided = "given", None, None, False
    if arrays.normals is not None:
        arrays, rule, disagreement, two_sided = _signs_checked(
            arrays, voxel_size, camera_location, origin
        )
        normals_from = "given" if rule is None else "re-oriented"
    fine = to_legacy(arrays).voxel_down_sample(egi_voxel_size or voxel_size / 4.0)
    coarse = fine.voxel_down_sample(voxel_size)
    _check_shape(np.asarray(coarse.points), voxel_size, name, len(arrays.points))
    if arrays.normals is None:
        radius = 2.5 * voxel_size if normal_radius is None else normal_radius
        fine.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=radius, max_nn=30))
        oriented, rule = orient(np.asarray(fine.points), np.asarray(fine.normals), voxel_size,
                                camera_location=camera_location, origin=origin)
        fine.normals = o3d.utility.Vector3dVector(oriented)
        normals_from = "estimated"
        coarse = fine.voxel_down_sample(voxel_size)  # again, averaging the new normals
    points = np.asarray(coarse.points).copy()
    point_normals = np.asarray(coarse.normals)
    norms = lengths(point_normals)[:, None]
    point_normals = np.divide(
        point_normals, norms, out=np.zeros_like(point_normals), where=norms > 1e-6
    )
    if normals_from == "estimated":
        normals, normal_points = np.asarray(fine.normals), np.asarray(fine.points)
    else:
        normals, normal_points = arrays.normals, arrays.points
    length = lengths(normals)
    keep = np.flatnonzero(length > 1e-6)
    if len(keep) < MIN_POINTS:
        raise ValueError(f"{name}: fewer than {MIN_POINTS} points have usable normals")
    if len(keep) > max_egi_points:  # an evenly spread subset (the EGI is normalised later)
        keep = keep[np.linspace(0, len(keep) - 1, max_egi_points).astype(np.int64)]
    unit, where = normals[keep] / length[keep, None], normal_points[keep].copy()
    flatness = float(np.linalg.norm(unit.mean(axis=0)))
    view = None if two_sided else _view(where, unit, voxel_size, origin)  # both sides: no view
    reading = CloudReading(normals_from, rule, view, disagreement, flatness, two_sided)
    return PreparedCloud(points, point_normals, unit, where, reading)
