"""Clouds in different units (o3d_spectral.io.units): refused, naming both extents, by the
check itself, by suggest_voxel_size and by ``register --voxel-size auto``."""

import numpy as np
import open3d as o3d
import pytest

import o3d_spectral
from o3d_spectral.cli import main
from o3d_spectral.io.units import MAX_EXTENT_RATIO, check_same_units, span
from tests.conftest import sample_model


@pytest.fixture(scope="module")
def model():
    """A mustard bottle in metres (about 0.2 m across)."""
    return np.asarray(sample_model("mustard_bottle", 3000).points)


def test_span_is_the_diagonal_without_stray_points():
    box = np.random.default_rng(0).uniform(0.0, [0.3, 0.4, 0.0], (10_000, 3))
    assert span(box) == pytest.approx(0.5, rel=0.02)
    strays = np.full((20, 3), 100.0)  # flying pixels, 0.2% of the points
    assert span(np.vstack([box, strays])) == pytest.approx(0.5, rel=0.02)


def test_millimetres_against_metres_are_named(model):
    with pytest.raises(ValueError, match="1000x") as refused:
        check_same_units(model, 1000.0 * model)
    message = str(refused.value)
    assert f"source spans {span(model):.3g} m, target {span(1000.0 * model):.3g} m" in message
    assert "same units (metres)" in message and "millimetres" in message
    assert "scale it by 0.001" in message and "\n" not in message
    with pytest.raises(ValueError, match="centimetres"):  # either way round
        check_same_units(100.0 * model, model)


def test_an_object_in_a_scene_passes_and_a_room_is_told_to_crop(model):
    room = np.random.default_rng(1).uniform(0.0, 1.0, (5000, 3))
    check_same_units(model, 5.0 * room / np.sqrt(3.0) * span(model) * 10.0)  # ~10x
    check_same_units(model, room * span(model) * (MAX_EXTENT_RATIO * 0.9) / np.sqrt(3.0))
    cup = 0.03 / span(model) * model  # a 3 cm object in a 5 m room: 170x
    with pytest.raises(ValueError, match="crop the target around it"):
        check_same_units(cup, 5.0 * room)


def test_clouds_without_extent_are_left_to_the_other_checks():
    check_same_units(np.ones((5, 3)), np.random.default_rng(0).uniform(size=(50, 3)))


def test_suggest_voxel_size_refuses_mixed_units(model):
    metres = model.copy()
    with pytest.raises(ValueError, match="same units"):
        o3d_spectral.suggest_voxel_size(model, 1000.0 * model)
    np.testing.assert_array_equal(model, metres)  # the caller's cloud is not modified


def test_register_auto_says_the_units_differ_in_one_line(model, tmp_path, capsys):
    paths = [tmp_path / "model.ply", tmp_path / "scan_mm.ply"]
    for path, points in zip(paths, (model, 1000.0 * model), strict=True):
        o3d.io.write_point_cloud(str(path), o3d.geometry.PointCloud(
            o3d.utility.Vector3dVector(points)))
    assert main(["register", *map(str, paths), "--voxel-size", "auto"]) != 0
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert out == "" and len(lines) == 1, err
    assert "1000x" in lines[0] and "same units" in lines[0]
