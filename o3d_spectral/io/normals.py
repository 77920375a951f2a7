"""Normals: their orientation, and what they say about how a cloud was captured.

A cloud's normals are usable by the method only when their signs are consistent: outward
on a model, towards the sensor on a scan. This module

- orients normals whose signs are not (:mod:`o3d_spectral.io.signs` tells when), or that
  were estimated (:func:`orient`): towards a known sensor; towards the origin for a depth
  map given in its sensor's frame (:func:`is_depth_map`); otherwise consistently along
  the surface and outward from the centroid;
- recognises a single view from its normals alone, in any frame
  (:func:`view_direction`: a sensor sees only surfaces facing it, so a view's normals lie
  in a hemisphere about the direction to the sensor).
"""

from __future__ import annotations

import numpy as np
import open3d as o3d
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from .constants import (
    ALONG_GAP,
    ALONG_SHARE,
    AROUND_ANGLE,
    DEPTH_BIN,
    DEPTH_GAP,
    DEPTH_SHARE,
    DISTANT_SENSOR,
    JOGGLE,
    OFF_AXIS_ANGLE,
    PROPAGATED_POINTS,
    SPREAD_TIE,
    VIEW_MEAN,
    VIEW_SHARE,
)
from .rows import bounds, largest_side, lengths, some
from .signs import SIGN_DISAGREEMENT, sign_disagreement

__all__ = [
    "VIEW_SHARE", "VIEW_MEAN", "is_depth_map", "is_depth_map_along", "sensor_direction", "faces",
    "orient", "view_direction", "sensor_position",
]


def is_depth_map(points: ArrayLike, viewpoint: ArrayLike, voxel_size: float) -> bool:
    """Whether ``points`` look like one depth image taken from ``viewpoint``.

    A sensor sees one surface per ray; a model (or a fusion of views) has surfaces behind
    surfaces. Rays are binned half a voxel wide at the cloud's median distance; the cloud
    is a depth map when fewer than 10% of the bins holding two points or more hold depths
    more than 3 voxels apart.

    Parameters
    ----------
    points : array_like, shape (N, 3)
        Metres.
    viewpoint : array_like, shape (3,)
        Metres.
    voxel_size : float
        Metres.
    """
    rays = np.asarray(points, dtype=np.float64) - np.asarray(viewpoint, dtype=np.float64)
    depth = np.linalg.norm(rays, axis=1)
    rays, depth = rays[depth > 0], depth[depth > 0]
    step = DEPTH_BIN * voxel_size / np.median(depth)  # bin width, radians
    theta = np.arccos(np.clip(rays[:, 2] / depth, -1.0, 1.0))
    phi = np.arctan2(rays[:, 1], rays[:, 0]) + np.pi
    row = np.floor(theta / step).astype(np.int64)
    per_row = np.maximum(np.floor(2 * np.pi * np.sin((row + 0.5) * step) / step), 1.0)
    key = row * (2 * int(np.ceil(2 * np.pi / step)) + 2) + np.floor(phi / (2 * np.pi) * per_row)
    return bool(_behind_share(key[None], depth[None], DEPTH_GAP * voxel_size)[0] < DEPTH_SHARE)


def is_depth_map_along(points: ArrayLike, direction: ArrayLike, voxel_size: float) -> bool:
    """Whether ``points`` look like one depth image taken by a distant sensor in
    ``direction`` (parallel rays): rays binned half a voxel wide, under
    :data:`ALONG_SHARE` of those holding two points or more hold depths more than
    :data:`ALONG_GAP` voxels apart. Stricter than :func:`is_depth_map`: without a sensor
    position a thin model (scissors: 29% of rays) would pass as a view (bundled real
    views: at most 3.6%; a bowl's single-sheet model, 3.9%, passes)."""
    p = np.asarray(points, dtype=np.float64)
    return bool(_surfaces_behind(p, direction, voxel_size)[0] < ALONG_SHARE)


def sensor_direction(
    points: ArrayLike, normals: ArrayLike, voxel_size: float, *,
    around: ArrayLike | None = None,
) -> NDArray[np.float64] | None:
    """The direction of a distant sensor that could have taken ``points``, or None.

    Directions about 16 degrees apart over the sphere (within 60 degrees of ``around``
    when given), then 3 degrees apart about the best, are tried on up to 2000 evenly
    spread points. Of those for which the points are a depth map
    (:func:`is_depth_map_along`) with the fewest rays meeting two surfaces, the one that
    sees every surface most squarely is kept (the largest 2nd percentile of
    ``|n . d|``: a sensor's view spans the normals about it). A single view has such
    directions, a model none.

    Parameters
    ----------
    points, normals : array_like, shape (N, 3)
        Metres; unit normals of any sign.
    voxel_size : float
        Metres.
    around : array_like, shape (3,), optional
        A unit direction to search about (e.g. a view's mean normal); the returned
        direction is then on its side.

    Returns
    -------
    ndarray, shape (3,), or None
        Unit direction (of either sign when ``around`` is not given).
    """
    pick = np.linspace(0, len(points) - 1, min(len(points), _DIRECTION_POINTS)).astype(np.int64)
    p = np.asarray(points, dtype=np.float64)[pick]
    n = np.asarray(normals, dtype=np.float64)[pick]
    candidates = _DIRECTIONS
    if around is not None:
        candidates = candidates * np.where(candidates @ around < 0.0, -1.0, 1.0)[:, None]
        candidates = candidates[candidates @ around >= np.cos(np.deg2rad(AROUND_ANGLE))]
    best = _best_direction(p, n, candidates, voxel_size)
    if best is None:
        return None
    return _best_direction(p, n, _turned_to(_CAP, best), voxel_size)  # finer, about it


def _best_direction(
    points: NDArray[np.float64], normals: NDArray[np.float64], candidates: NDArray[np.float64],
    voxel_size: float,
) -> NDArray[np.float64] | None:
    """Of ``candidates`` (K, 3), those along which ``points`` meet the fewest second
    surfaces, if under :data:`ALONG_SHARE`; of them the one seeing the normals most
    squarely (2nd percentile of ``|n . d|``); None when none qualifies."""
    spreads = _surfaces_behind(points, candidates, voxel_size)
    if len(spreads) == 0 or spreads.min() >= ALONG_SHARE:
        return None
    kept = candidates[spreads <= spreads.min() + SPREAD_TIE]
    squareness = np.percentile(np.abs(normals @ kept.T), 2, axis=0)
    return kept[int(np.argmax(squareness))]


def _turned_to(directions: NDArray[np.float64], axis: NDArray[np.float64]) -> NDArray[np.float64]:
    """``directions`` (K, 3) about +z turned so that +z goes to the unit ``axis``."""
    z = np.array([0.0, 0.0, 1.0])
    v, c = np.cross(z, axis), float(z @ axis)
    if np.linalg.norm(v) < 1e-12:
        return directions if c > 0 else -directions
    K = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    R = np.eye(3) + K + K @ K / (1.0 + c)
    return directions @ R.T


def _surfaces_behind(
    points: NDArray[np.float64], directions: ArrayLike, voxel_size: float
) -> NDArray[np.float64]:
    """For each of ``directions`` (K, 3): the share of the rays parallel to it, half a
    voxel apart, holding two points or more, whose depths are more than
    :data:`ALONG_GAP` voxels apart (1 when none holds two); shape (K,)."""
    d = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    helper = np.where((np.abs(d[:, 0]) < 0.9)[:, None], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    u = np.cross(d, helper)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    across = [np.floor(points @ axis.T / (0.5 * voxel_size)).T for axis in (u, np.cross(d, u))]
    a, b = (c - c.min(axis=1, keepdims=True) for c in across)  # (K, N) each
    key = a * (b.max(axis=1, keepdims=True) + 1) + b
    return _behind_share(key, (points @ d.T).T, ALONG_GAP * voxel_size)


def _behind_share(key: NDArray, depth: NDArray[np.float64], gap: float) -> NDArray[np.float64]:
    """Per row of ``key`` (K, N: each point's ray, whole numbers from 0) and ``depth``
    (K, N, metres): the share of the rays holding two points or more whose depths are
    more than ``gap`` metres apart; 1 for a row where no ray holds two. Shape (K,)."""
    rows, n = key.shape
    if key.max() < 2**16:  # keys of 16 bits: NumPy's stable sort is then a radix sort
        key = key.astype(np.uint16)
        order = np.argsort(key, axis=1, kind="stable")
    else:
        order = np.argsort(key, axis=1)  # a ray's depths in any order
    key, depth = np.take_along_axis(key, order, 1), np.take_along_axis(depth, order, 1)
    first = np.ones(key.shape, dtype=bool)
    first[:, 1:] = np.diff(key, axis=1) != 0
    starts = np.flatnonzero(first)  # each row starts a ray: rays never span two rows
    depth = depth.ravel()
    spread = np.maximum.reduceat(depth, starts) - np.minimum.reduceat(depth, starts)
    shared = np.diff(np.r_[starts, rows * n]) >= 2
    row = starts[shared] // n
    total = np.bincount(row, minlength=rows)
    behind = np.bincount(row, weights=spread[shared] > gap, minlength=rows)
    return np.where(total > 0, behind / np.maximum(total, 1), 1.0)


def _fibonacci_hemisphere(count: int) -> NDArray[np.float64]:
    """``count`` unit vectors spread evenly over the hemisphere z > 0, shape (count, 3)."""
    i = np.arange(count) + 0.5
    z = 1.0 - i / count
    angle = np.pi * (1.0 + 5.0**0.5) * i
    r = np.sqrt(1.0 - z * z)
    return np.stack([r * np.cos(angle), r * np.sin(angle), z], axis=1)


#: Candidate sensor directions (:func:`sensor_direction`): one of each opposite pair,
#: about 16 degrees apart; then those of a 12-degree cap about +z, 3 degrees apart,
#: turned about the best.
_DIRECTIONS = _fibonacci_hemisphere(80)
_CAP = _fibonacci_hemisphere(3000)
_CAP = _CAP[_CAP[:, 2] >= np.cos(np.deg2rad(12.0))]
_DIRECTION_POINTS = 2000


def orient(
    points: NDArray[np.float64], normals: NDArray[np.float64], voxel_size: float, *,
    camera_location: ArrayLike | None = None, origin: ArrayLike | None = None,
) -> tuple[NDArray[np.float64], str]:
    """Normals with their signs chosen, and the rule that chose them.

    Rules, in order: towards ``camera_location`` when given (``"camera"``); towards
    ``origin`` when the cloud is a depth map seen from an origin outside its bounding box,
    the normals so turned agree with their neighbours, and the origin lies within 45
    degrees of the view's axis (``"sensor frame"``: a scan in its sensor's frame; a scan
    whose frame has its origin beside it, as the dragon's, can pass the depth-map test
    from there and would come out inside out); towards the side of a distant
    sensor for which the cloud is a depth map (``"hemisphere"``: a view in another frame,
    :func:`sensor_direction`); otherwise one orientation propagated
    along the surface (``"surface"``: a model). The last two are then turned outward from
    the centroid (a view's surface bulges towards its sensor).

    Parameters
    ----------
    points, normals : ndarray, shape (N, 3)
        Metres; unit normals of any sign. Not modified.
    voxel_size : float
        Metres (the depth-map test's resolution).
    camera_location, origin : array_like, shape (3,), optional
        Metres; ``origin``: where the caller's frame has its origin (zero when omitted).
    """
    origin = np.zeros(3) if origin is None else np.asarray(origin, dtype=np.float64)
    lower, upper = bounds(points)
    outside = np.any(lower > origin) or np.any(upper < origin)
    if camera_location is not None:
        return _turned_to_face(normals, np.asarray(camera_location) - points), "camera"
    axis = sensor_direction(points, normals, voxel_size)
    if outside and is_depth_map(points, origin, voxel_size):
        toward = _turned_to_face(normals, origin - points)  # a scan in its sensor's frame,
        split = sign_disagreement(points, toward) > SIGN_DISAGREEMENT  # unless that splits
        ray = origin - points.mean(axis=0)  # it or the origin is off the view's axis
        off_axis = np.cos(np.deg2rad(OFF_AXIS_ANGLE)) * np.linalg.norm(ray)
        aside = axis is not None and abs(ray @ axis) < off_axis
        if not (split or aside):
            return toward, "sensor frame"
    if axis is not None:  # one view, in another frame
        oriented, rule = _turned_to_face(normals, axis), "hemisphere"
    else:
        oriented, rule = _propagated(points, normals), "surface"
    if _outward_share(points, oriented) < 0.0:
        oriented = -oriented  # outward: a view bulges towards its sensor
    return oriented, rule


def _outward_share(points: NDArray[np.float64], normals: NDArray[np.float64]) -> float:
    """Mean of ``n . (p - centroid)`` (metres): positive when the normals point outward
    on the whole (a closed surface, or a view of a body seen from outside)."""
    return float(np.mean(np.einsum("ij,ij->i", normals, points - points.mean(axis=0))))


def _turned_to_face(normals: NDArray[np.float64], reference: ArrayLike) -> NDArray[np.float64]:
    """Each normal (N, 3) with the sign that makes its dot product with ``reference``
    (shape (3,) or (N, 3)) non-negative."""
    dots = np.einsum("ij,ij->i", normals, np.broadcast_to(reference, normals.shape))
    return np.where((dots < 0.0)[:, None], -normals, normals)


def faces(
    points: ArrayLike, normals: ArrayLike, place: ArrayLike, share: float = VIEW_SHARE
) -> bool:
    """Whether at least ``share`` of the (non-zero) ``normals`` (N, 3) at ``points``
    (metres) face ``place`` (metres, shape (3,)): a view seen from there (False when none
    is non-zero)."""
    n = np.asarray(normals, dtype=np.float64)
    usable = some(n != 0.0)
    if not usable.any():
        return False
    rays = np.asarray(place, dtype=np.float64) - np.asarray(points, dtype=np.float64)
    return bool(np.mean(np.einsum("ij,ij->i", n, rays)[usable] > 0.0) >= share)


def _propagated(points: NDArray[np.float64], normals: NDArray[np.float64]) -> NDArray[np.float64]:
    """The normals turned to one consistent orientation along the surface.

    The orientation is propagated (Open3D's minimum spanning tree over tangent planes,
    whose cost grows fast with the number of points) over every k-th point, at most
    ``PROPAGATED_POINTS``, with their own normals, centred at the origin; then each
    normal takes the sign of the nearest propagated one. A plane (no spread across it)
    takes one side of it.
    """
    centred = points - points.mean(axis=0)  # Qhull loses precision far from the origin
    spread = np.linalg.svd(centred[:: max(len(points) // 2000, 1)], compute_uv=False)
    if spread[2] < 1e-6 * spread[0]:  # a plane: one normal, and nothing for Qhull to do
        _, _, axes = np.linalg.svd(centred[:: max(len(points) // 2000, 1)])
        reference = np.broadcast_to(axes[2], normals.shape)
    else:
        step = int(np.ceil(len(points) / PROPAGATED_POINTS))
        coarse = centred[::step]
        _, nearest = cKDTree(coarse).query(centred)
        reference = _consistent(coarse, normals[::step])[nearest]
    return _turned_to_face(normals, reference)


def _consistent(points: NDArray[np.float64], normals: NDArray[np.float64]) -> NDArray[np.float64]:
    """Open3D's ``orient_normals_consistent_tangent_plane(10)`` on ``points`` (N, 3),
    metres, centred. Its graph comes from a Delaunay triangulation, which Qhull refuses for
    exactly cospherical points (a perfect sphere): those are tried again moved by
    :data:`JOGGLE` of their extent at most (seeded), far below any normal's scale."""

    def propagated(where: NDArray[np.float64]) -> NDArray[np.float64]:
        cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(where))
        cloud.normals = o3d.utility.Vector3dVector(normals)
        cloud.orient_normals_consistent_tangent_plane(10)
        return np.asarray(cloud.normals)

    try:
        return propagated(points)
    except RuntimeError:  # Qhull: "input sites are cocircular or cospherical"
        jitter = np.random.default_rng(0).uniform(-1.0, 1.0, points.shape)
        return propagated(points + JOGGLE * largest_side(points) * jitter)


def view_direction(
    points: ArrayLike, normals: ArrayLike, voxel_size: float
) -> NDArray[np.float64] | None:
    """The direction towards the sensor of a single view, or None for anything else.

    A sensor sees only the surfaces that face it, and samples each in proportion to its
    projected area, so a view's consistently oriented normals lie in a hemisphere about
    the direction to the sensor, their mean about 1/2 to 2/3 long; a model's (a closed
    surface) average to nearly zero. The cloud is a view when at least
    :data:`VIEW_SHARE` of its normals lie within 90 degrees of their mean, the mean is at
    least :data:`VIEW_MEAN` long, and the points are a depth map for a distant sensor
    within 60 degrees of the mean (:func:`sensor_direction`): that sensor's direction is
    returned (the mean normal leans towards the largest faces: 25-50 degrees off on the
    YCB-Video crops).

    Parameters
    ----------
    points : array_like, shape (N, 3)
        Where the normals are, metres.
    normals : array_like, shape (N, 3)
        Unit (or zero) normals, consistently oriented.
    voxel_size : float
        Metres.

    Returns
    -------
    ndarray, shape (3,), or None
        Unit direction from the surface towards the (distant) sensor.
    """
    n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    usable = lengths(n) > 1e-6
    if not usable.any():
        return None
    mean = n[usable].mean(axis=0)
    length = float(np.linalg.norm(mean))
    if length < VIEW_MEAN or np.mean(n[usable] @ mean > 0.0) < VIEW_SHARE:
        return None
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)[usable]
    return sensor_direction(points, n[usable], voxel_size, around=mean / length)


def sensor_position(
    points: NDArray[np.float64], point_normals: NDArray[np.float64],
    view: NDArray[np.float64] | None, origin: NDArray[np.float64],
) -> NDArray[np.float64] | None:
    """Where the sensor of a single view was, or None when the cloud is not one.

    ``origin`` (metres, shape (3,)) when at least :data:`VIEW_SHARE` of the voxels'
    normals face it (a view in its sensor's frame); otherwise, for a view recognised from
    its normals (``view``, :func:`view_direction`), a point far along ``view`` from the
    points' centroid (a distant sensor: its rays are parallel, towards ``view``).

    Parameters
    ----------
    points, point_normals : ndarray, shape (M, 3)
        One point per voxel (metres) and its mean normal (unit or zero).
    view : ndarray, shape (3,), or None
    origin : ndarray, shape (3,)
    """
    if faces(points, point_normals, origin):
        return origin
    if view is None:
        return None
    size = largest_side(points)
    return points.mean(axis=0) + DISTANT_SENSOR * max(size, 1.0) * view
