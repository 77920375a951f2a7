"""The synthetic room's fragments: their frames, their pairs' truth, the overlap rule."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from o3d_spectral.spectra.so3 import exp
from o3d_spectral.synthetic.room import Fragment, RoomOptions, fragment_pairs, room_fragments

SMALL = RoomOptions(fragments=8, frames_per_fragment=2, frame_step=20.0, spacing=0.02)


@pytest.fixture(scope="module")
def fragments() -> list[Fragment]:
    return room_fragments(SMALL, 7)


def _nearest(points: np.ndarray, other: np.ndarray) -> np.ndarray:
    return cKDTree(other).query(points)[0]


def test_fragments_are_in_their_first_cameras_frame(fragments):
    for fragment in fragments:
        assert len(fragment.points) > 1000
        assert np.median(fragment.points[:, 2]) > 0.5  # in front of the camera
        R = fragment.world_from_fragment[:3, :3]
        np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
        # the camera looks out and down: its optical axis points below the horizon
        assert R[2, 2] < 0


def test_the_pairs_truth_lays_one_fragment_on_the_other(fragments):
    pairs = fragment_pairs(fragments)
    assert (0, 1) in pairs and (2, 3) in pairs  # neighbours an eighth of a turn apart
    for (i, j), T in pairs.items():
        moved = fragments[j].points @ T[:3, :3].T + T[:3, 3]
        near = _nearest(moved, fragments[i].points)
        shared = near < 0.05
        lying = np.median(near[shared])
        assert lying < 0.6 * SMALL.spacing  # half the spacing and the noise, where they overlap
        for axis in ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]):  # the truth 3 degrees off: farther
            turned = moved @ exp(np.deg2rad(3.0) * np.array(axis)).T
            assert np.median(_nearest(turned, fragments[i].points)[shared]) > 1.5 * lying


def test_pairs_follow_the_overlap_rule():
    rng = np.random.default_rng(0)
    points = rng.uniform(-1.0, 1.0, (2000, 3))
    away = np.eye(4)
    away[:3, 3] = [5.0, 0.0, 0.0]
    placed_away = Fragment(points - away[:3, 3], away)  # the same points, seen from 5 m
    fragments = [Fragment(points, np.eye(4)), placed_away, Fragment(points, away)]
    pairs = fragment_pairs(fragments, overlap=0.3, distance=0.01)
    assert sorted(pairs) == [(0, 1)]  # the third lies 5 m away
    np.testing.assert_allclose(pairs[(0, 1)], away)
    far = rng.uniform(10.0, 12.0, (2000, 3))
    for shared, paired in ((400, False), (800, True)):  # of the smaller cloud's 2000
        other = Fragment(np.concatenate([points[:shared], far]), np.eye(4))
        assert (fragment_pairs([fragments[0], other], 0.3, 0.01) == {}) is not paired


def test_the_same_seed_gives_the_same_room():
    a, b = (room_fragments(RoomOptions(fragments=2, frames_per_fragment=1), 3) for _ in range(2))
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x.points, y.points)
        np.testing.assert_array_equal(x.world_from_fragment, y.world_from_fragment)
