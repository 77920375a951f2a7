"""Multiway registration with the clouds' camera positions: a join that would put one
scan's points in space another's camera saw empty is passed over."""

from __future__ import annotations

import numpy as np
import pytest

import o3d_spectral
from o3d_spectral.multiway.registration import maximum_spanning_tree, poses_from_pairs

VOXEL = 0.05
#: The three cameras' positions in the first one's frame (the world), metres.
CAMERAS = ((0.0, 0.0, 0.0), (-0.3, 0.0, 0.0), (0.3, 0.0, 0.2))


def corner() -> np.ndarray:
    """A room's corner in the world (N, 3): a wall 2 m ahead, a floor 1 m below the
    cameras (y down), a side wall 1.5 m to their right; 2 cm grid."""
    u = np.arange(-1.5, 1.5, 0.02)
    a, b = np.meshgrid(u, u)
    a, b = a.ravel(), b.ravel()
    keep = (a < 1.5) & (b < 1.0)
    front = np.c_[a, b, np.full(a.size, 2.0)][keep]
    floor = np.c_[a, np.full(a.size, 1.0), 0.5 + 0.5 * b][(a < 1.5) & (b < 1.0)]
    side = np.c_[np.full(a.size, 1.5), 0.5 * (a - 0.5), 0.5 + 0.5 * b][(b < 1.0)]
    return np.r_[front, floor, side]


def scans_and_records(wrong_fit: float) -> tuple[list, list, list]:
    """The corner seen from the three cameras, each scan in its camera's frame (the
    cameras only move), and records of pairs (0, 1) and (0, 2) exact; (1, 2) has its
    scan 1 moved 1 m towards camera 2, with fit ``wrong_fit``."""
    points = corner()
    scans = [points - camera for camera in CAMERAS]
    truths = []
    for camera in CAMERAS:
        pose = np.eye(4)
        pose[:3, 3] = camera
        truths.append(pose)

    def record(i: int, j: int, fit: float, shift: float = 0.0):
        relative = np.linalg.inv(truths[j]) @ truths[i]
        relative[2, 3] -= shift
        return o3d_spectral.PairwiseRecord(i, j, relative, fit, fit, 0.0, kept=False,
                                           uncertain=True)

    return scans, truths, [record(0, 1, 0.5), record(0, 2, 0.5),
                           record(1, 2, wrong_fit, shift=1.0)]


def test_a_join_that_puts_points_in_free_space_is_passed_over():
    scans, truths, records = scans_and_records(wrong_fit=0.95)
    blind = poses_from_pairs(scans, VOXEL, records)
    assert abs(blind.poses[2][2, 3] - truths[2][2, 3]) == pytest.approx(1.0)  # the wrong pair
    seen = poses_from_pairs(scans, VOXEL, records, camera_locations=[np.zeros(3)] * 3)
    for pose, truth in zip(seen.poses, truths, strict=True):
        assert np.abs(pose - truth).max() < 1e-6
    assert not [r for r in seen.pairs if (r.source, r.target) == (1, 2)][0].kept


def test_every_cloud_of_one_branch_is_tested_against_every_cloud_of_the_other():
    """Scan 1's camera unknown: the wrong pair (1, 2) joins first, then scan 0 would join
    them through (0, 1) and lie where scan 2's camera saw empty space: passed over, as
    the wrong pair itself would be. With one camera only, nothing is tested."""
    scans, truths, records = scans_and_records(wrong_fit=0.95)
    result = poses_from_pairs(scans, VOXEL, records, camera_locations=[np.zeros(3), None,
                                                                        np.zeros(3)])
    assert np.abs(result.poses[2] - truths[2]).max() < 1e-6
    alone = poses_from_pairs(scans, VOXEL, records, camera_locations=[None, None,
                                                                       np.zeros(3)])
    assert abs(alone.poses[2][2, 3] - truths[2][2, 3]) == pytest.approx(1.0)


def test_kruskal_passes_over_a_join_refused_and_takes_the_next():
    """Four nodes in a chain of heavy edges and a light one; the heavy edge to node 3
    would place it 1 m off, where the test refuses it: the light edge places it."""
    weighted = [(0, 1, 0.9), (1, 2, 0.8), (2, 3, 0.7), (0, 3, 0.1)]
    moves = {(i, j): np.eye(4) for i, j, _ in weighted}
    moves[(2, 3)] = np.eye(4)
    moves[(2, 3)][0, 3] = 1.0
    assert maximum_spanning_tree(4, weighted) == [(0, 1), (1, 2), (2, 3)]
    tested = []

    def joinable(a: int, b: int, a_to_b: np.ndarray) -> bool:
        tested.append((a, b))
        return bool(np.allclose(a_to_b, np.eye(4)))

    assert maximum_spanning_tree(4, weighted, moves, joinable) == [(0, 1), (1, 2), (0, 3)]
    # Each join tests every cloud of one tree against every cloud of the other, and
    # stops at the first refusal.
    assert tested == [(0, 1), (0, 2), (1, 2), (0, 3), (0, 3), (1, 3), (2, 3)]


@pytest.mark.parametrize(("cameras", "match"), [
    ([np.zeros(3)] * 2, r"one position \(or None\) per cloud: 3 clouds, got 2"),
    ([np.zeros(3), [0.0, np.inf, 0.0], None], r"camera_locations\[1\] must be finite"),
])
def test_the_public_call_refuses_camera_locations_before_any_work(cameras, match, monkeypatch):
    from o3d_spectral.multiway import registration

    def no_work(*args, **kwargs):
        raise AssertionError("the clouds were prepared before camera_locations was checked")

    monkeypatch.setattr(registration, "prepare", no_work)
    scans, _, _ = scans_and_records(wrong_fit=0.95)
    with pytest.raises(ValueError, match=match):
        o3d_spectral.registration_multiway(scans, VOXEL, camera_locations=cameras)
