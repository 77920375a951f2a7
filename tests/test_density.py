"""Dense clouds read one point per quarter-voxel cell (o3d_spectral.io.density)."""

import numpy as np
import open3d as o3d
import pytest

import o3d_spectral
from o3d_spectral.io.cloud import CloudArrays, as_arrays
from o3d_spectral.io.density import CELL, first_per_cell, read_at_voxels
from o3d_spectral.spectra import so3
from o3d_spectral.synthetic.sampling import rigid
from tests.conftest import sample_model

VOXEL = 0.008


@pytest.fixture(scope="module")
def dense_pair():
    """A drill sampled at about 300 points per voxel about the origin (where a call does
    not centre the clouds again), and a copy turned and shifted."""
    source = sample_model("power_drill", n=200_000, seed=0)
    source.translate(-source.get_center())
    T = rigid(so3.exp(np.deg2rad(25.0) * np.array([0.3, 0.8, -0.5]) / np.linalg.norm(
        [0.3, 0.8, -0.5])), np.array([0.02, -0.01, 0.03]))
    target = o3d.geometry.PointCloud(sample_model("power_drill", n=200_000, seed=1))
    target.translate(-np.asarray(sample_model("power_drill", n=200_000, seed=0).get_center()))
    target.transform(T)
    return source, target, T


def test_a_cloud_at_usual_density_is_read_whole():
    arrays = as_arrays(sample_model("power_drill", n=3000), "cloud")
    read, index = read_at_voxels(arrays, VOXEL)
    assert read is arrays and index is None


def test_a_dense_cloud_keeps_its_first_point_in_each_quarter_voxel_cell(dense_pair):
    arrays = as_arrays(dense_pair[0], "source")
    read, index = read_at_voxels(arrays, VOXEL)
    assert index is not None and len(arrays.points) > 4 * len(index)
    assert np.all(np.diff(index) > 0)  # ascending: actual points, in the cloud's order
    np.testing.assert_array_equal(read.points, arrays.points[index])
    np.testing.assert_array_equal(read.normals, arrays.normals[index])
    cells = np.floor((read.points - arrays.points.min(axis=0)) / (CELL * VOXEL))
    assert len(np.unique(cells, axis=0)) == len(index)  # one point per cell
    assert np.array_equal(first_per_cell(arrays.points, CELL * VOXEL), index)


def test_a_cloud_of_too_few_cells_is_read_whole_and_refused_with_its_own_count():
    points = np.repeat(np.eye(3) * 0.001, 100, axis=0)
    read, index = read_at_voxels(CloudArrays(points, None), VOXEL)
    assert index is None and len(read.points) == 300


def test_a_dense_pair_registers_with_the_callers_indices(dense_pair):
    source, target, T = dense_pair
    result = o3d_spectral.registration_spectral_global(source, target, VOXEL)
    E = np.linalg.inv(T) @ result.transformation
    assert so3.rotation_angle(E[:3, :3]) < np.deg2rad(1.0)
    pairs = np.asarray(result.correspondence_set)
    assert len(pairs) and pairs[:, 0].max() < len(source.points)
    posed = np.asarray(source.points)[pairs[:, 0]] @ result.transformation[:3, :3].T
    posed += result.transformation[:3, 3]
    gaps = np.linalg.norm(posed - np.asarray(target.points)[pairs[:, 1]], axis=1)
    assert gaps.max() <= result.max_correspondence_distance + 1e-12


def test_prepared_dense_clouds_read_the_same_points(dense_pair):
    """A prepared source is down-sampled before the call centres the clouds on the
    target, an unprepared one after: the voxel means differ in their last bits, hence
    the tolerance; the points read are the same."""
    source, target, _ = dense_pair
    alone = o3d_spectral.registration_spectral_global(source, target, VOXEL)
    prepared = o3d_spectral.registration_spectral_global(
        o3d_spectral.prepare(source, VOXEL), o3d_spectral.prepare_target(target, VOXEL), VOXEL)
    np.testing.assert_allclose(alone.transformation, prepared.transformation, atol=1e-9)
    np.testing.assert_array_equal(np.asarray(alone.correspondence_set),
                                  np.asarray(prepared.correspondence_set))
