"""The batched phase correlation: peaks equal to one correlation each, on both backends."""

import subprocess
import sys

import numpy as np
import pytest

from o3d_spectral.correlation import (
    ArrayBackend,
    BatchedCorrelation,
    CompiledBackend,
    TurnedCloud,
)
from o3d_spectral.spectra import so3
from o3d_spectral.spectra.fft import RealFFT3
from o3d_spectral.spectra.grid import Box, Lattice, splat
from o3d_spectral.spectra.translation import cross_power_peak

MOVING = (16, 16, 16)
FIXED = (20, 18, 22)


@pytest.fixture
def cloud(rng):
    """A lumpy cloud of 400 points about its pivot (voxels), the pivot mid-grid, with
    outward normals."""
    points = rng.normal(size=(400, 3)) * [3.0, 2.0, 1.5]
    normals = points / np.linalg.norm(points, axis=1, keepdims=True)
    return points, normals


def reference_peak(moving_grid, fixed_grid, shape):
    """One correlation by the spectra module: padded grids, ``cross_power_peak``."""
    fft = RealFFT3(shape)
    pad = np.zeros(shape)
    pad[: moving_grid.shape[0], : moving_grid.shape[1], : moving_grid.shape[2]] = moving_grid
    F = np.array(fft.forward(pad))
    pad = np.zeros(shape)
    pad[: fixed_grid.shape[0], : fixed_grid.shape[1], : fixed_grid.shape[2]] = fixed_grid
    return cross_power_peak(F, np.array(fft.forward(pad)), fft, positive_below=fixed_grid.shape)


def scene(cloud, rotation, at, weighting="trilinear"):
    """The cloud turned by ``rotation`` about its pivot and splatted on the fixed grid with
    the pivot at ``at`` (voxels)."""
    points, _ = cloud
    return BatchedCorrelation.grid_of(TurnedCloud(points, at, weighting=weighting), FIXED,
                                      rotation)


@pytest.mark.parametrize("weighting", ["trilinear", "count", "binary"])
def test_heights_and_shifts_are_those_of_one_correlation_each(cloud, rng, weighting):
    points, _ = cloud
    truth = so3.exp([0.3, -0.5, 0.2])
    fixed = scene(cloud, truth, [9.0, 9.0, 11.0], weighting)
    moving = TurnedCloud(points, [8.0, 8.0, 8.0], weighting=weighting)
    rotations = np.stack([truth, *so3.uniform_rotations(7)])
    correlation = BatchedCorrelation(fixed, MOVING)
    peaks = correlation.peaks(moving, rotations)
    for R, height, shift, fraction in zip(rotations, peaks.heights, peaks.shifts,
                                          peaks.fractions, strict=True):
        one = reference_peak(BatchedCorrelation.grid_of(moving, MOVING, R), fixed,
                             correlation.shape)
        assert height == pytest.approx(one.peak, rel=1e-4)
        assert np.abs(shift - one.shift).max() <= 0.5  # the integer peak of its sub-voxel one
        np.testing.assert_allclose(shift + fraction, one.shift, atol=1e-3)  # single precision
    assert np.argmax(peaks.heights) == 0  # the truth peaks highest ...
    assert peaks.heights[0] > 0.6
    np.testing.assert_array_equal(peaks.shifts[0], [1, 1, 3])  # ... where the pivot moved


def test_the_splat_is_the_grid_modules_of_the_turned_points(cloud):
    points, normals = cloud
    R, offset = so3.exp([1.0, 0.2, -0.4]), np.array([8.2, 7.9, 8.4])
    for weighting in ("trilinear", "count", "binary"):
        turned = TurnedCloud(points, offset, weighting=weighting)
        box = Box(Lattice(np.zeros(3), 1.0), np.zeros(3, dtype=np.int64), MOVING)
        expected = splat(points @ R.T + offset, box, mode=weighting)
        for backend in (CompiledBackend(), ArrayBackend()):
            grid = BatchedCorrelation.grid_of(turned, MOVING, R, backend)
            np.testing.assert_allclose(grid, expected, atol=1e-5)


@pytest.mark.parametrize("two_sided", [False, True])
def test_both_backends_cull_alike_and_agree(cloud, two_sided):
    points, normals = cloud
    viewpoint = np.array([8.0, 8.0, 40.0])
    culled = TurnedCloud(points, [8.0, 8.0, 8.0], normals=normals, viewpoint=viewpoint,
                         two_sided=two_sided, min_facing=10)
    rotations = so3.uniform_rotations(9)
    for R in rotations:  # the points facing the sensor, as the stepper culls them
        u = points @ R.T + 8.0
        cosine = np.sum((normals @ R.T) * (viewpoint - u), axis=1)
        facing = cosine != 0 if two_sided else cosine > 0
        box = Box(Lattice(np.zeros(3), 1.0), np.zeros(3, dtype=np.int64), MOVING)
        np.testing.assert_allclose(BatchedCorrelation.grid_of(culled, MOVING, R),
                                   splat(u[facing], box), atol=1e-5)
    fixed = scene(cloud, rotations[3], [10.0, 9.0, 11.0])
    for searched, at in ((None, (2, 1, 3)), ((6, 4, 7), (-3, 5, 8))):  # inside; astride
        compiled, array = (BatchedCorrelation(fixed, MOVING, backend=backend, searched=searched,
                                              overlap=fixed, overlap_at=at).peaks(culled,
                                                                                  rotations)
                           for backend in (CompiledBackend(), ArrayBackend()))
        assert np.all(compiled.overlaps > 0)
        np.testing.assert_allclose(array.heights, compiled.heights, rtol=1e-4)
        np.testing.assert_array_equal(array.shifts, compiled.shifts)
        np.testing.assert_allclose(array.fractions, compiled.fractions, atol=1e-3)
        np.testing.assert_allclose(array.overlaps, compiled.overlaps, rtol=1e-6)
        if searched:
            assert np.all((compiled.shifts >= 0) & (compiled.shifts < searched))


def test_the_overlap_is_the_unit_moving_grids_inner_product_before_any_shift(cloud):
    points, _ = cloud
    fixed = scene(cloud, np.eye(3), [9.0, 9.0, 9.0])
    moving = TurnedCloud(points, [8.0, 8.0, 8.0])
    overlap = np.random.default_rng(2).uniform(size=MOVING)
    rotations = so3.uniform_rotations(5)
    peaks = BatchedCorrelation(fixed, MOVING, overlap=overlap).peaks(moving, rotations)
    for R, found in zip(rotations, peaks.overlaps, strict=True):
        grid = BatchedCorrelation.grid_of(moving, MOVING, R).astype(np.float64)
        assert found == pytest.approx(np.sum(grid * overlap) / np.linalg.norm(grid), rel=1e-12)
    # A larger grid, the moving grid's corner anywhere in it (or astride its edges): the
    # inner product over the cells they share, the moving grid's norm over all of it.
    larger = np.random.default_rng(3).uniform(size=(20, 18, 22))
    for at in [(2, 1, 3), (-4, 6, 15), (0, -16, 0), (20, 0, 0)]:
        padded = np.zeros((60, 60, 60))
        padded[20:40, 20:38, 20:42] = larger
        on_moving = padded[tuple(slice(20 + a, 20 + a + n) for a, n in zip(at, MOVING,
                                                                           strict=True))]
        expected = BatchedCorrelation(fixed, MOVING, overlap=on_moving).peaks(moving, rotations)
        # the array backend splats in another order: its single-precision grids differ
        for backend, rtol in ((CompiledBackend(), 1e-12), (ArrayBackend(), 1e-6)):
            found = BatchedCorrelation(fixed, MOVING, backend=backend, overlap=larger,
                                       overlap_at=at).peaks(moving, rotations)
            np.testing.assert_allclose(found.overlaps, expected.overlaps, rtol=rtol, atol=0)
        if at[1] == -16:  # nothing shared
            np.testing.assert_array_equal(expected.overlaps, 0.0)
    unasked = BatchedCorrelation(fixed, MOVING).peaks(moving, rotations)
    np.testing.assert_array_equal(unasked.overlaps, 0.0)
    np.testing.assert_array_equal(unasked.heights, peaks.heights)


def test_too_few_facing_points_splat_them_all(cloud):
    points, normals = cloud
    away = TurnedCloud(points, [8.0, 8.0, 8.0], normals=normals, viewpoint=[8.0, 8.0, 8.0],
                       min_facing=10)  # a sensor inside the cloud sees only inner faces
    plain = TurnedCloud(points, [8.0, 8.0, 8.0])
    for backend in (CompiledBackend(), ArrayBackend()):
        np.testing.assert_array_equal(BatchedCorrelation.grid_of(away, MOVING, None, backend),
                                      BatchedCorrelation.grid_of(plain, MOVING, None, backend))


def test_the_same_peaks_whatever_the_workers(cloud):
    points, _ = cloud
    fixed = scene(cloud, np.eye(3), [9.0, 9.0, 9.0])
    moving = TurnedCloud(points, [8.0, 8.0, 8.0])
    correlation = BatchedCorrelation(fixed, MOVING)
    rotations = so3.uniform_rotations(40)
    assert len(rotations) > 2 * correlation.backend.batch_size(correlation.shape)
    one = correlation.peaks(moving, rotations, workers=1)
    for workers in (2, 3, None):
        other = correlation.peaks(moving, rotations, workers=workers)
        for mine, theirs in zip(other, one, strict=True):
            np.testing.assert_array_equal(mine, theirs)


class Cramped(CompiledBackend):
    """A backend whose memory holds ``room`` grids at most."""

    def __init__(self, room: int) -> None:
        super().__init__()
        self.room = room

    def batch_size(self, shape):
        return 8

    def correlate(self, cloud, rotations, batch, fixed):
        if min(batch, len(rotations)) > self.room:
            raise MemoryError("out of memory")
        return super().correlate(cloud, rotations, batch, fixed)


def test_a_batch_that_does_not_fit_is_split_and_gives_the_same_peaks(cloud):
    points, _ = cloud
    fixed = scene(cloud, np.eye(3), [9.0, 9.0, 9.0])
    moving = TurnedCloud(points, [8.0, 8.0, 8.0])
    rotations = so3.uniform_rotations(20)
    roomy = BatchedCorrelation(fixed, MOVING).peaks(moving, rotations)
    cramped = BatchedCorrelation(fixed, MOVING, backend=Cramped(3)).peaks(moving, rotations)
    for mine, theirs in zip(cramped, roomy, strict=True):
        np.testing.assert_array_equal(mine, theirs)
    with pytest.raises(MemoryError, match=r"one FFT grid of \d+x\d+x\d+ voxels.*voxel_size"):
        BatchedCorrelation(fixed, MOVING, backend=Cramped(0)).peaks(moving, rotations)


def test_bad_arguments_are_named(cloud):
    points, normals = cloud
    with pytest.raises(ValueError, match="shifts would wrap around"):
        BatchedCorrelation(np.zeros(FIXED), MOVING, shape=(16, 16, 16))
    with pytest.raises(ValueError, match="fixed must be a 3D grid"):
        BatchedCorrelation(np.zeros((4, 4)), MOVING)
    with pytest.raises(ValueError, match=r"searched \(0, 4, 4\) must lie within"):
        BatchedCorrelation(np.zeros(FIXED), MOVING, searched=(0, 4, 4))
    with pytest.raises(ValueError, match=r"overlap must be a 3D grid"):
        BatchedCorrelation(np.zeros(FIXED), MOVING, overlap=np.zeros((3, 3)))
    for at in [(1, 2), (0.5, 0.0, 0.0)]:
        with pytest.raises(ValueError, match=r"overlap_at must be 3 whole numbers"):
            BatchedCorrelation(np.zeros(FIXED), MOVING, overlap=np.zeros(FIXED), overlap_at=at)
    with pytest.raises(ValueError, match="weighting must be one of"):
        TurnedCloud(points, np.zeros(3), weighting="nearest")
    with pytest.raises(ValueError, match="normals must have shape"):
        TurnedCloud(points, np.zeros(3), normals=normals[:3], viewpoint=np.zeros(3))
    with pytest.raises(ValueError, match="given together"):
        TurnedCloud(points, np.zeros(3), normals=normals)
    with pytest.raises(TypeError, match="backend must be"):
        BatchedCorrelation(np.zeros(FIXED), MOVING, backend="cuda")


def test_the_layer_runs_without_open3d():
    """The batched correlation imports no Open3D: it runs where only NumPy is (a GPU
    machine with CuPy)."""
    code = (
        "import sys, numpy as np\n"
        "class Block:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name.split('.')[0] == 'open3d': raise ImportError('no open3d here')\n"
        "sys.meta_path.insert(0, Block())\n"
        "from o3d_spectral.correlation import BatchedCorrelation, TurnedCloud\n"
        "cloud = TurnedCloud(np.random.default_rng(0).normal(size=(50, 3)), [6.0, 6.0, 6.0])\n"
        "fixed = BatchedCorrelation.grid_of(cloud, (12, 12, 12))\n"
        "peaks = BatchedCorrelation(fixed, (12, 12, 12)).peaks(cloud, np.eye(3)[None])\n"
        "assert peaks.heights[0] > 0.99 and 'open3d' not in sys.modules\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
