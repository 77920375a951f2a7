"""Free space: where a depth camera saw through, no surface of another scan may lie.

A camera that measured a surface at range ``r`` along a ray saw empty space before it.
Two scans placed right never put one's points in the other's empty space, beyond noise;
a wrong placement that fits well (a room's floor and walls laid on another part of the
room) often does. This is the free-space violation test of Huber and Hebert ("Fully
automatic registration of multiple 3D data sets", Image and Vision Computing 21, 2003).

A scan seen from its camera is a :class:`RangeImage`: the nearest range in each
direction, directions binned on the faces of a cube round the camera (no pole where
bins shrink to nothing). :func:`in_free_space` is the share of another scan's points,
among those in directions the image saw, that lie nearer to its camera than its surface;
:func:`free_space_violation` takes the larger of the two ways round.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..common.checks import check_point
from .tree import Joinable

__all__ = ["RangeImage", "range_image", "in_free_space", "free_space_violation",
           "free_space_test", "checked_cameras"]


@dataclass(frozen=True)
class RangeImage:
    """A scan seen from its camera.

    Attributes
    ----------
    camera : ndarray, shape (3,)
        The camera's position in the scan's frame, metres.
    step : float
        Width of a direction bin, in tangent units on a cube face (about radians near a
        face's centre).
    keys : ndarray, shape (K,), int64
        The bins the scan has points in, sorted (:func:`_bins`).
    ranges : ndarray, shape (K,), float64
        The nearest point's range in each bin, metres: the surface the camera saw.
    """

    camera: NDArray[np.float64]
    step: float
    keys: NDArray[np.int64]
    ranges: NDArray[np.float64]


def range_image(points: NDArray[np.floating], camera: NDArray[np.floating],
                step: float) -> RangeImage:
    """The nearest range of ``points`` (N, 3) in each direction from ``camera`` (3,),
    directions binned ``step`` wide (tangent units on a cube face)."""
    camera = np.asarray(camera, dtype=np.float64)
    keys, ranges = _bins(np.asarray(points, dtype=np.float64) - camera, step)
    order = np.argsort(keys, kind="stable")
    unique, first = np.unique(keys[order], return_index=True)
    return RangeImage(camera, step, unique, np.minimum.reduceat(ranges[order], first))


def in_free_space(image: RangeImage, points: NDArray[np.floating], margin: float) -> float:
    """The share of ``points`` (N, 3), in the image's frame, that lie nearer to its camera
    than the surface it saw in their direction by more than ``margin`` metres, among
    those in directions it saw (0 when it saw none of them)."""
    keys, ranges = _bins(np.asarray(points, dtype=np.float64) - image.camera, image.step)
    slot = np.minimum(np.searchsorted(image.keys, keys), len(image.keys) - 1)
    seen = image.keys[slot] == keys
    count = int(np.count_nonzero(seen))
    if count == 0:
        return 0.0
    return float(np.count_nonzero(ranges[seen] < image.ranges[slot[seen]] - margin)) / count


def free_space_violation(
    image_a: RangeImage, points_a: NDArray[np.floating], image_b: RangeImage,
    points_b: NDArray[np.floating], a_to_b: NDArray[np.floating], margin: float,
) -> float:
    """The larger share of either scan's points in the other's free space
    (:func:`in_free_space`) when ``a_to_b`` (4, 4) maps scan a's frame onto scan b's.

    ``points_a`` and ``points_b`` are the points tested (a down-sample will do); the
    images hold the surfaces they are tested against."""
    a_to_b = np.asarray(a_to_b, dtype=np.float64)
    b_to_a = np.linalg.inv(a_to_b)
    a_in_b = points_a @ a_to_b[:3, :3].T + a_to_b[:3, 3]
    b_in_a = points_b @ b_to_a[:3, :3].T + b_to_a[:3, 3]
    return max(in_free_space(image_b, a_in_b, margin), in_free_space(image_a, b_in_a, margin))


def free_space_test(
    points: Sequence[NDArray[np.float64]], tested: Sequence[NDArray[np.float64]],
    cameras: Sequence[NDArray[np.float64] | None], margin: float, voxel_size: float,
    max_share: float,
) -> Joinable | None:
    """The test of :func:`o3d_spectral.multiway.tree.maximum_spanning_tree`: clouds ``a``
    and ``b`` may lie as ``a_to_b`` places them when at most ``max_share`` of either's
    ``tested`` points (its down-sample) lie in space the other's camera saw empty, over
    ``margin`` metres short of the surface it saw in its ``points``
    (:func:`free_space_violation`; direction bins one ``voxel_size`` wide at the cloud's
    median range). A cloud whose camera is None is never refused; None when fewer than
    two clouds have a camera: nothing to test."""
    if sum(c is not None for c in cameras) < 2:
        return None
    images = [None if camera is None else range_image(p, camera, _bin_width(p, camera,
                                                                            voxel_size))
              for p, camera in zip(points, cameras, strict=True)]
    known: dict[tuple[int, int, bytes], bool] = {}  # the tree may be built more than once

    def joinable(a: int, b: int, a_to_b: NDArray[np.float64]) -> bool:
        image_a, image_b = images[a], images[b]
        if image_a is None or image_b is None:
            return True
        key = (a, b, a_to_b.tobytes())
        if key not in known:
            known[key] = free_space_violation(image_a, tested[a], image_b, tested[b], a_to_b,
                                              margin) <= max_share
        return known[key]

    return joinable


def checked_cameras(
    camera_locations: Sequence[object | None] | None, n: int
) -> list[NDArray[np.float64] | None]:
    """Each of ``n`` clouds' camera position (3,), metres, in its own frame (None where
    unknown); all None for ``camera_locations`` None. One per cloud (a sequence, or an
    array of shape (n, 3)), each None or three finite coordinates, else refused naming
    ``camera_locations[k]``."""
    if camera_locations is None:
        return [None] * n
    if isinstance(camera_locations, str) or not hasattr(camera_locations, "__len__"):
        raise TypeError("camera_locations must be a sequence holding one position (or "
                        f"None) per cloud, got {type(camera_locations).__qualname__}")
    if len(camera_locations) != n:
        raise ValueError(f"camera_locations must hold one position (or None) per cloud: "
                         f"{n} clouds, got {len(camera_locations)}")
    points = [check_point(f"camera_locations[{k}]", c) for k, c in enumerate(camera_locations)]
    return [None if p is None else np.array(p) for p in points]


def _bin_width(points: NDArray[np.float64], camera: NDArray[np.float64],
               voxel_size: float) -> float:
    """A range image's direction bins: one voxel wide at the cloud's median range."""
    reach = float(np.median(np.linalg.norm(points - camera, axis=1)))
    return voxel_size / max(reach, voxel_size)


def _bins(rays: NDArray[np.float64], step: float) -> tuple[NDArray[np.int64],
                                                            NDArray[np.float64]]:
    """Each ray's (N, 3) direction bin on the cube round the camera and its length.

    A ray falls on the face of its largest component (6 faces); the other two components
    over it, in [-1, 1], are cut into ``step``-wide bins."""
    ranges = np.linalg.norm(rays, axis=1)
    axis = np.argmax(np.abs(rays), axis=1)
    rows = np.arange(len(rays))
    major = rays[rows, axis]
    face = 2 * axis + (major < 0)
    safe = np.where(major == 0.0, 1.0, np.abs(major))
    u = rays[rows, (axis + 1) % 3] / safe
    v = rays[rows, (axis + 2) % 3] / safe
    per_side = int(np.ceil(2.0 / step)) + 1
    iu = np.clip(np.floor((u + 1.0) / step), 0, per_side - 1).astype(np.int64)
    iv = np.clip(np.floor((v + 1.0) / step), 0, per_side - 1).astype(np.int64)
    return (face * per_side + iu) * per_side + iv, ranges
