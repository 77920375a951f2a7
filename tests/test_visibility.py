"""Free space: a scan's points nearer to another's camera than the surface it saw there."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from o3d_spectral.multiway.visibility import (
    checked_cameras,
    free_space_violation,
    in_free_space,
    range_image,
)

STEP = 0.01


def wall(depth: float, half: float = 1.0, count: int = 101) -> np.ndarray:
    """A square of points ``2 half`` wide at ``z = depth`` (N, 3), metres."""
    u = np.linspace(-half, half, count)
    x, y = np.meshgrid(u, u)
    return np.c_[x.ravel(), y.ravel(), np.full(x.size, depth)]


@pytest.mark.parametrize(("depth", "share"), [(1.0, 1.0), (1.95, 0.0), (2.0, 0.0), (3.0, 0.0)])
def test_points_before_the_surface_a_camera_saw_are_in_its_free_space(depth, share):
    """A wall 2 m ahead: points on the camera's side of it by more than the margin
    (0.1 m) are all in free space; on it, within the margin or behind it, none."""
    image = range_image(wall(2.0), np.zeros(3), STEP)
    assert in_free_space(image, wall(depth, half=0.5 * depth / 2.0, count=31), 0.1) == share


def test_points_in_directions_the_camera_did_not_see_are_not_counted():
    image = range_image(wall(2.0, half=0.2), np.zeros(3), STEP)
    aside = wall(1.0, half=0.1) + [1.0, 0.0, 0.0]  # 45 degrees off, beyond the wall's edge
    assert in_free_space(image, aside, 0.1) == 0.0
    half_seen = np.r_[wall(1.0, half=0.05, count=11), aside[:121]]
    assert in_free_space(image, half_seen, 0.1) == 1.0  # the share among those seen


def test_every_direction_round_the_camera_has_a_bin():
    """Points all round the camera (every face of the cube, and its edges) are seen by
    their own image and none lies before itself."""
    directions = Rotation.random(4000, random_state=0).apply([1.0, 0.0, 0.0])
    points = 3.0 * directions
    image = range_image(points, np.zeros(3), 0.05)
    assert in_free_space(image, points, 0.01) == 0.0
    assert in_free_space(image, 0.5 * points, 0.01) == 1.0


def test_the_share_does_not_depend_on_the_frame_or_the_units():
    """The same scans turned (a turn that maps the cube of direction bins onto itself)
    and moved together, or in millimetres (margin too): the same share."""
    rng = np.random.default_rng(1)
    # Jittered, so that no point lies on a bin's edge, where rounding decides the bin.
    a, b = (wall(2.0, half) + rng.normal(0.0, 0.01, (101 * 101, 3)) for half in (1.0, 0.8))
    b[:, 2] += 0.5 * b[:, 0]  # a wall leaning through the other: part before it, part behind
    a_to_b = np.eye(4)
    a_to_b[:3, 3] = (0.05, -0.03, 0.0)
    expected = free_space_violation(range_image(a, np.zeros(3), STEP), a,
                                    range_image(b, np.zeros(3), STEP), b, a_to_b, 0.05)
    assert 0.0 < expected < 1.0
    motion = np.eye(4)
    motion[:3, :3] = [[0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]]
    motion[:3, 3] = (4.0, -2.0, 7.0)
    moved_a, moved_b = a @ motion[:3, :3].T + motion[:3, 3], b @ motion[:3, :3].T + motion[:3, 3]
    camera = motion[:3, 3]
    moved = free_space_violation(range_image(moved_a, camera, STEP), moved_a,
                                 range_image(moved_b, camera, STEP), moved_b,
                                 motion @ a_to_b @ np.linalg.inv(motion), 0.05)
    scaled = a_to_b.copy()
    scaled[:3, 3] *= 1000.0
    millimetres = free_space_violation(range_image(1000.0 * a, np.zeros(3), STEP), 1000.0 * a,
                                       range_image(1000.0 * b, np.zeros(3), STEP), 1000.0 * b,
                                       scaled, 50.0)
    assert moved == pytest.approx(expected, abs=1e-12)
    assert millimetres == pytest.approx(expected, abs=1e-12)


def test_the_violation_is_the_larger_share_of_the_two_ways():
    """A near wall in front of a far one: the near wall's points lie in the far scan's
    free space; the far wall's lie behind the near scan's surface, in none."""
    far, near = wall(3.0), wall(1.0, half=0.3, count=31)
    far_image, near_image = range_image(far, np.zeros(3), STEP), range_image(near, np.zeros(3),
                                                                             STEP)
    assert in_free_space(far_image, near, 0.1) == 1.0
    assert in_free_space(near_image, far, 0.1) == 0.0
    assert free_space_violation(near_image, near, far_image, far, np.eye(4), 0.1) == 1.0


@pytest.mark.parametrize(("cameras", "error", "match"), [
    ([np.zeros(3)], ValueError, r"one position \(or None\) per cloud: 2 clouds, got 1"),
    ([np.zeros(3), [0.0, np.nan, 0.0]], ValueError, r"camera_locations\[1\] must be finite"),
    ([np.zeros(3), [0.0, 1.0]], ValueError, r"camera_locations\[1\] must be three"),
    ([np.zeros(3), "origin"], TypeError, r"camera_locations\[1\] must be three"),
    ("origin", TypeError, "camera_locations must be a sequence"),
    (3, TypeError, "camera_locations must be a sequence"),
])
def test_camera_locations_are_checked_naming_the_entry(cameras, error, match):
    with pytest.raises(error, match=match):
        checked_cameras(cameras, 2)


def test_camera_locations_may_leave_a_cloud_without_a_camera():
    cameras = checked_cameras([None, (1, 2, 3)], 2)
    assert cameras[0] is None and cameras[1].tolist() == [1.0, 2.0, 3.0]
    assert checked_cameras(None, 3) == [None, None, None]
    assert [c.tolist() for c in checked_cameras(np.ones((2, 3)), 2)] == [[1.0] * 3] * 2
