"""The final polish (o3d_spectral.refinement.icp): the ICP cut to the points that can correspond."""

import numpy as np
import open3d as o3d
import pytest
from scipy.spatial import cKDTree

from o3d_spectral.harness.real import load_cases
from o3d_spectral.refinement import icp as refinement
from o3d_spectral.refinement.icp import REACH, point_to_plane_icp, polish_within_reach
from o3d_spectral.spectra import so3

VOXEL = 0.005
DISTANCE = 0.4 * VOXEL  # the polish's correspondence distance


@pytest.fixture(scope="module")
def scans():
    """Dragon scans 72 degrees apart (a fifth of their surface shared), target normals."""
    case = load_cases(["dragon_72"])[0]
    target = o3d.geometry.PointCloud(case.target)
    target.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=2 * VOXEL, max_nn=30))
    return case.source, target, case.T_gt


def turned(pose: np.ndarray, degrees: float) -> np.ndarray:
    """``pose`` (4, 4) turned by ``degrees`` about an oblique axis through the origin."""
    axis = np.array([0.3, -0.8, 0.5]) / np.linalg.norm([0.3, -0.8, 0.5])
    out = pose.copy()
    out[:3, :3] = so3.exp(np.deg2rad(degrees) * axis) @ pose[:3, :3]
    return out


def counted_icp(monkeypatch) -> list:
    """The cut (or whole) point count and the start of each ICP :func:`polish_within_reach`
    runs."""
    calls = []

    def icp(source, target, max_distance, init, cut_from=None):
        calls.append((len(source.points), init))
        return point_to_plane_icp(source, target, max_distance, init, cut_from)

    monkeypatch.setattr(refinement, "point_to_plane_icp", icp)
    return calls


def test_the_cut_polish_is_the_whole_sources_icp_to_the_bit(scans, monkeypatch):
    source, target, truth = scans
    start = turned(truth, 1.0)
    whole = point_to_plane_icp(source, target, DISTANCE, start)
    calls = counted_icp(monkeypatch)
    cut = polish_within_reach(source, target, cKDTree(np.asarray(target.points)), DISTANCE,
                              start)
    np.testing.assert_array_equal(cut, whole)
    assert len(calls) == 1 and calls[0][0] < len(source.points) / 2  # most left out


def moves_beyond_reach(source, start: np.ndarray, pose: np.ndarray) -> bool:
    """Whether ``pose`` moves some point of ``source`` by over the reach from ``start``."""
    moved = np.asarray(source.points) @ (pose[:3, :3] - start[:3, :3]).T
    return np.max(np.linalg.norm(moved + pose[:3, 3] - start[:3, 3], axis=1)) > REACH * DISTANCE


def test_a_pose_that_moves_a_point_left_out_beyond_reach_is_cut_again(scans, monkeypatch):
    source, target, truth = scans
    start = turned(truth, 4.0)  # the ICP moves the scan's far end by more than the reach
    whole = point_to_plane_icp(source, target, DISTANCE, start)
    assert moves_beyond_reach(source, start, whole)
    calls = counted_icp(monkeypatch)
    cut = polish_within_reach(source, target, cKDTree(np.asarray(target.points)), DISTANCE,
                              start)
    assert 1 < len(calls) <= refinement.RECUTS
    assert all(count < len(source.points) for count, _ in calls)  # never the whole scan
    # the whole scan's ICP from where the last cut was made, to the bit
    np.testing.assert_array_equal(
        cut, point_to_plane_icp(source, target, DISTANCE, calls[-1][1]))
    # and where the whole scan's ICP from the start ends, within a hundredth of a degree
    turn = cut[:3, :3] @ whole[:3, :3].T
    assert np.degrees(np.arccos(min(1.0, (np.trace(turn) - 1) / 2))) < 0.01
    assert np.linalg.norm(cut[:3, 3] - whole[:3, 3]) < 2e-5  # metres


def test_the_whole_source_is_polished_once_the_cuts_are_spent(scans, monkeypatch):
    source, target, truth = scans
    start = turned(truth, 4.0)
    monkeypatch.setattr(refinement, "RECUTS", 1)
    calls = counted_icp(monkeypatch)
    cut = polish_within_reach(source, target, cKDTree(np.asarray(target.points)), DISTANCE,
                              start)
    assert [count for count, _ in calls][-1] == len(source.points)
    reached = calls[-1][1]  # the first cut's pose, beyond reach of the start
    assert moves_beyond_reach(source, start, reached)
    np.testing.assert_array_equal(cut, point_to_plane_icp(source, target, DISTANCE, reached))


def test_a_polish_at_half_the_voxel_reads_fewer_points_and_lands_near_the_whole_one(
    scans, monkeypatch
):
    """``RefinementOption(cell=0.5)``: both clouds one point per half-voxel cube, as the
    lean FPFH-RANSAC polishes; from a start 2 degrees off, the pose as near the recorded
    truth as the full polish's (0.44 and 0.50 degrees), within a millimetre of it."""
    from o3d_spectral import RefinementOption

    source, target, truth = scans
    start = turned(truth, 2.0)
    whole = refinement.refine(source, target, VOXEL, start, RefinementOption())
    calls = counted_icp(monkeypatch)
    thin = refinement.refine(source, target, VOXEL, start, RefinementOption(cell=0.5))
    assert max(n for n, _ in calls) < len(source.points) / 2

    def error(pose):
        return np.rad2deg(so3.rotation_angle(pose[:3, :3].T @ truth[:3, :3]))

    assert error(thin) < error(whole) + 0.1 and error(whole) < 1.0
    assert np.linalg.norm(thin[:3, 3] - whole[:3, 3]) < 1e-3


def test_evenly_spread_keeps_count_points_first_and_last_with_their_normals():
    points = np.arange(30.0).reshape(10, 3)
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    cloud.normals = o3d.utility.Vector3dVector(-points)
    assert refinement.evenly_spread(cloud, 10) is cloud  # within the budget: itself
    spread = refinement.evenly_spread(cloud, 4)
    np.testing.assert_array_equal(np.asarray(spread.points), points[[0, 3, 6, 9]])
    np.testing.assert_array_equal(np.asarray(spread.normals), -points[[0, 3, 6, 9]])


def test_a_source_over_the_budget_is_polished_on_that_many_points(scans, monkeypatch):
    """The final ICP reads at most ``MAX_POLISH_POINTS`` of the source (its cut within
    reach of the target drawn from them); on a fifth of a dragon scan the pose from a
    start 2 degrees off is as near the recorded truth as the whole scan's (0.48 and 0.50
    degrees), within half a millimetre of it (0.1 mm)."""
    from o3d_spectral import RefinementOption

    source, target, truth = scans
    start = turned(truth, 2.0)
    calls = counted_icp(monkeypatch)
    whole = refinement.refine(source, target, VOXEL, start, RefinementOption())
    assert len(source.points) <= refinement.MAX_POLISH_POINTS  # read whole
    cut = max(n for n, _ in calls)
    calls.clear()
    monkeypatch.setattr(refinement, "MAX_POLISH_POINTS", len(source.points) // 5)
    spread = refinement.refine(source, target, VOXEL, start, RefinementOption())
    assert max(n for n, _ in calls) < min(cut, len(source.points) // 5)

    def error(pose):
        return np.rad2deg(so3.rotation_angle(pose[:3, :3].T @ truth[:3, :3]))

    assert error(spread) < error(whole) + 0.1 and error(whole) < 1.0
    assert np.linalg.norm(spread[:3, 3] - whole[:3, 3]) < 5e-4  # metres
