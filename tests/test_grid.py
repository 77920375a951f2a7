import numpy as np
import pytest

from o3d_spectral.spectra.grid import Lattice, check_memory, splat


@pytest.fixture
def box():
    return Lattice(np.array([-0.1, -0.1, -0.1]), 0.01).box_around([-0.1] * 3, [0.1] * 3, 1)


def test_trilinear_preserves_mass_and_centroid(box, rng):
    points = rng.uniform(-0.08, 0.08, size=(500, 3))
    grid = splat(points, box, mode="trilinear")
    assert grid.sum() == pytest.approx(500.0)
    centres = [box.corner[a] + (np.arange(box.shape[a]) + 0.5) * 0.01 for a in range(3)]
    mean = [np.sum(grid.sum(axis=tuple(b for b in range(3) if b != a)) * centres[a]) / 500
            for a in range(3)]
    np.testing.assert_allclose(mean, points.mean(axis=0), atol=1e-12)


def test_count_and_binary(box):
    points = np.array([[0.001, 0.001, 0.001], [0.002, 0.003, 0.004], [0.05, 0.05, 0.05]])
    counts = splat(points, box, mode="count")
    assert counts.sum() == 3 and counts.max() == 2
    binary = splat(points, box, mode="binary")
    assert binary.sum() == 2 and binary.max() == 1


@pytest.mark.slow
def test_points_outside_are_dropped_and_out_buffer_is_used(box):
    out = np.full((box.shape[0] + 5,) * 3, 7.0)
    grid = splat(np.array([[5.0, 5.0, 5.0], [0.0, 0.0, 0.0]]), box, mode="count", out=out)
    assert grid is out and out.sum() == 1.0


def test_unknown_mode(box):
    with pytest.raises(ValueError, match="mode"):
        splat(np.zeros((1, 3)), box, mode="nearest")


def test_memory_budget():
    check_memory((100, 100, 100), 2**30, "grid")
    with pytest.raises(ValueError, match="GiB.*metres"):
        check_memory((2000, 2000, 2000), 2**30, "grid")
