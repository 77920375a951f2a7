"""The voxel-size advice (o3d_spectral.suggest_voxel_size) and ``register --voxel-size auto``."""

import json

import numpy as np
import open3d as o3d
import pytest

import o3d_spectral
from o3d_spectral.cli import main
from o3d_spectral.harness.errors import rotation_error
from o3d_spectral.spectra import so3
from o3d_spectral.voxel import suggestion as voxel
from tests.conftest import sample_model


def plane(side: float, n: int, seed: int = 0) -> np.ndarray:
    """``n`` points uniform on a square ``side`` metres wide (z = 0)."""
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(0.0, side, (n, 2)), np.zeros(n)])


def box_surface(sides, n: int, seed: int = 0) -> np.ndarray:
    """``n`` points uniform on the surface of a box with ``sides`` (metres)."""
    rng = np.random.default_rng(seed)
    a, b, c = sides
    areas = np.array([b * c, b * c, a * c, a * c, a * b, a * b])
    face = rng.choice(6, size=n, p=areas / areas.sum())
    points = rng.uniform(0.0, 1.0, (n, 3)) * np.asarray(sides)
    axis = face // 2
    points[np.arange(n), axis] = np.where(face % 2 == 0, 0.0, np.asarray(sides)[axis])
    return points


@pytest.fixture(scope="module")
def drill():
    source = sample_model("power_drill", 6000)
    T = np.eye(4)
    T[:3, :3] = so3.exp(np.deg2rad(100.0) * np.array([0.48, 0.6, -0.64]))
    T[:3, 3] = [0.03, -0.05, 0.02]
    return source, o3d.geometry.PointCloud(source).transform(T), T


def test_spacing_is_the_side_of_the_surface_each_point_stands_for():
    # uniform on a 0.5 m square: 0.25 m^2 over 10000 points, a 5 mm square each
    assert voxel.spacing(plane(0.5, 10_000)) == pytest.approx(0.005, rel=0.05)
    # every point of a 5000-point sample doubled: its nearest neighbours are at 0, but
    # the spacing counts points per area (10000 on 0.25 m^2)
    doubled = np.repeat(plane(0.5, 5_000), 2, axis=0)
    assert voxel.spacing(doubled) == pytest.approx(0.005, rel=0.1)


def test_spacing_of_a_large_cloud_is_measured_on_a_subset_with_the_same_answer():
    dense = plane(1.0, 4 * voxel.MAX_TREE_POINTS)  # 1 m^2 over 200000 points
    assert voxel.spacing(dense) == pytest.approx(np.sqrt(1.0 / len(dense)), rel=0.05)
    assert voxel.spacing(dense) == voxel.spacing(dense.copy())  # seeded: reproducible


def test_the_sparser_cloud_sets_the_size_when_it_is_sparse():
    sparse, dense = box_surface((0.1, 0.08, 0.06), 800), box_surface((0.1, 0.08, 0.06), 20_000)
    expected = voxel.SPACINGS * voxel.spacing(sparse)
    assert expected > 0.15 / voxel.VOXELS_ACROSS  # this term is the largest here
    assert voxel.suggest_voxel_size(sparse, dense) == pytest.approx(expected)
    assert voxel.suggest_voxel_size(dense, sparse) == pytest.approx(expected)


def test_a_dense_object_is_given_its_diameter_over_voxels_across():
    obj = box_surface((0.2, 0.1, 0.05), 60_000)
    diameter = float(np.linalg.norm([0.2, 0.1, 0.05]))
    assert voxel.suggest_voxel_size(obj, obj) == pytest.approx(
        diameter / voxel.VOXELS_ACROSS, rel=0.01)


def test_a_whole_scene_sets_a_coarser_size_by_its_diameter():
    obj = box_surface((0.05, 0.04, 0.03), 20_000)
    scene = np.vstack([plane(1.5, 150_000, seed=1), obj + [0.5, 0.5, 0.0]])
    suggested = voxel.suggest_voxel_size(obj, scene)
    assert suggested == pytest.approx(np.hypot(1.5, 1.5) / voxel.MAX_VOXELS_ACROSS, rel=0.01)
    assert suggested > voxel.SPACINGS * voxel.spacing(scene)


def test_scaling_the_clouds_scales_the_size():
    source, target = box_surface((0.1, 0.07, 0.04), 3000), box_surface((0.1, 0.07, 0.04), 9000, 1)
    base = voxel.suggest_voxel_size(source, target)
    for k in (0.01, 7.0, 1000.0):
        assert voxel.suggest_voxel_size(k * source, k * target) == pytest.approx(k * base,
                                                                                 rel=1e-9)


def test_isolated_points_do_not_change_the_size():
    obj = box_surface((0.2, 0.1, 0.05), 60_000)
    strays = np.random.default_rng(3).uniform(1.5, 2.0, (20, 3))  # flying pixels 2 m off
    assert voxel.suggest_voxel_size(obj, np.vstack([obj, strays])) == pytest.approx(
        voxel.suggest_voxel_size(obj, obj), rel=0.01)


def test_every_cloud_type_gives_the_same_size_and_none_is_modified(drill):
    source, target, _ = drill
    before = np.asarray(target.points).copy()
    legacy = o3d_spectral.suggest_voxel_size(source, target)
    tensor = o3d.t.geometry.PointCloud.from_legacy(target)
    assert o3d_spectral.suggest_voxel_size(source, tensor) == legacy
    with_normals = np.hstack([np.asarray(target.points), np.asarray(target.normals)])
    assert o3d_spectral.suggest_voxel_size(np.asarray(source.points), with_normals) == legacy
    np.testing.assert_array_equal(np.asarray(target.points), before)
    assert target.has_normals()


@pytest.mark.parametrize(("source", "target", "error", "named"), [
    (np.zeros((0, 3)), np.ones((5, 3)), ValueError, "source"),
    (np.ones((50, 3)), np.full((50, 3), np.nan), ValueError, "target"),
    ("model.ply", np.ones((5, 3)), TypeError, "source"),
    (np.ones((50, 3)), np.ones((50, 4)), ValueError, "target"),
    (np.ones((50, 3)), np.eye(3)[[0, 1] * 25], ValueError, "source"),
])
def test_bad_clouds_are_refused_naming_the_argument(source, target, error, named):
    with pytest.raises(error, match=named):
        o3d_spectral.suggest_voxel_size(source, target)


def test_the_suggested_size_registers(drill):
    source, target, T = drill
    size = o3d_spectral.suggest_voxel_size(source, target)
    result = o3d_spectral.registration_spectral_global(source, target, size)
    assert rotation_error(result.transformation, T) < 2.0


def test_register_voxel_size_rule_uses_and_prints_the_suggestion(drill, tmp_path, capsys):
    source, target, T = drill
    paths = [tmp_path / "source.ply", tmp_path / "target.ply"]
    for path, cloud in zip(paths, (source, target), strict=True):
        o3d.io.write_point_cloud(str(path), cloud)
    read = [o3d.io.read_point_cloud(str(path)) for path in paths]
    assert main(["register", *map(str, paths), "--voxel-size", "rule", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["voxel_size"] == pytest.approx(o3d_spectral.suggest_voxel_size(*read))
    assert summary["max_correspondence_distance"] == pytest.approx(summary["voxel_size"])
    assert rotation_error(np.array(summary["transformation"]), T) < 2.0
    assert main(["-v", "register", *map(str, paths), "--voxel-size", "RULE"]) == 0
    out, err = capsys.readouterr()
    assert "--voxel-size rule:" in err and "(rule)" in out
    assert main(["register", *map(str, paths), "--voxel-size", "auto", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    trial = o3d_spectral.voxel_trial(*read)
    assert summary["voxel_size"] == pytest.approx(trial.voxel_size)
    np.testing.assert_allclose(summary["transformation"], trial.result.transformation,
                               atol=1e-9)
    assert main(["-v", "register", *map(str, paths), "--voxel-size", "AUTO"]) == 0
    out, err = capsys.readouterr()
    assert "--voxel-size auto:" in err and "tried" in err and "(auto)" in out
    assert main(["register", *map(str, paths), "--voxel-size", "0.01", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["voxel_size"] == 0.01
    assert main(["register", *map(str, paths), "--voxel-size", "automatic"]) == 2
    assert "--voxel-size" in capsys.readouterr().err
