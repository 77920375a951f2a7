"""Refusals of unusable clouds name the real problem: too few points, normals all zero, a
mesh file read as a point cloud (and no numpy warning before them)."""

import warnings

import numpy as np
import open3d as o3d
import pytest

import o3d_spectral
from o3d_spectral.cli import main
from o3d_spectral.io.normals import faces

VOXEL = 0.01


@pytest.fixture(scope="module")
def target():
    return np.random.default_rng(0).normal(size=(2000, 3)) * 0.05


@pytest.mark.parametrize("call", [o3d_spectral.registration_spectral,
                                  o3d_spectral.registration_spectral_global])
def test_a_three_point_cloud_is_told_it_has_too_few_points(target, call):
    with pytest.raises(ValueError, match="source has 3 points; the method needs at least 10") \
            as refused:
        call(target[:3], target, VOXEL)
    assert "voxel_size" not in str(refused.value)


def test_too_few_voxels_name_the_points_and_a_rounded_voxel(target):
    corners = np.array([[0.0, 0.0, 0.0], [0.5, 0.0, 0.0], [0.0, 0.5, 0.0], [0.0, 0.0, 0.5]])
    clusters = np.repeat(corners, 50, axis=0) + 0.001 * target[:200]  # 4 tight clusters
    with pytest.raises(ValueError, match=r"occupies 4 voxels of 0\.1111 m \(its 200 points\)"):
        o3d_spectral.registration_spectral(clusters, clusters, 1.0 / 9.0)


def test_all_zero_normals_are_refused_without_numpy_warnings(target):
    source = np.hstack([target, np.zeros_like(target)])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ValueError, match="source: its normals are all zero; give unit"):
            o3d_spectral.registration_spectral_global(source, target, VOXEL)
        assert not faces(target, np.zeros_like(target), np.zeros(3))


def test_a_mesh_read_as_a_point_cloud_is_told_how_to_sample_it(target, tmp_path):
    path = tmp_path / "box.obj"
    o3d.io.write_triangle_mesh(str(path), o3d.geometry.TriangleMesh.create_box(0.1, 0.2, 0.05))
    empty = o3d.io.read_point_cloud(str(path))
    with pytest.raises(ValueError, match=r"source is empty; .*read_point_cloud.*sample_points"):
        o3d_spectral.registration_spectral(empty, target, VOXEL)


def test_register_on_a_mesh_of_few_vertices_says_to_sample_it(target, tmp_path, capsys):
    """The command reads a mesh file's vertices: a box's 8 are too few, and it says so."""
    paths = [tmp_path / "box.obj", tmp_path / "scan.ply"]
    o3d.io.write_triangle_mesh(str(paths[0]), o3d.geometry.TriangleMesh.create_box(0.1, 0.2, 0.05))
    o3d.io.write_point_cloud(str(paths[1]), o3d.geometry.PointCloud(
        o3d.utility.Vector3dVector(target)))
    assert main(["register", *map(str, paths), "--voxel-size", "0.01"]) != 0
    err = capsys.readouterr().err
    assert "source has 8 points" in err and "sample_points_uniformly" in err, err
    assert "smaller voxel_size" not in err
