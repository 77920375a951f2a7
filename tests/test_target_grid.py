"""TargetGrid.correlate (the law's phase correlation, on the compiled loop) against the
paper's steps in double precision from NumPy: splat, unit norm, cross-power, peak."""

import numpy as np
import pytest

from o3d_spectral.spectra.fft import RealFFT3
from o3d_spectral.spectra.grid import splat
from o3d_spectral.spectra.target_grid import TargetGrid
from o3d_spectral.spectra.translation import cross_power_peak

VOXEL = 0.01


def reference(grid: TargetGrid, moved, radius, centre, around):
    """The shift, peak and ``J_t`` of ``moved`` as the paper computes them, in double
    precision on the FFT grid ``grid`` chooses."""
    box = grid.moving_box(radius, centre)
    fixed = grid.search_box(radius, around)
    shape = grid.fft_shape(fixed, box, radius)
    searched = grid.searched(fixed, box, radius)
    moving = splat(moved, box, mode=grid.weighting)
    moving /= np.linalg.norm(moving)
    fft = RealFFT3(shape)
    padded = [np.zeros(shape), np.zeros(shape)]
    padded[0][tuple(slice(0, n) for n in box.shape)] = moving
    padded[1][tuple(slice(0, n) for n in fixed.shape)] = grid.block(fixed)
    F, G = (np.array(fft.forward(p)) for p in padded)
    bounds = {"positive_below": fixed.shape} if searched is None else {"searched": searched}
    peak = cross_power_peak(F, G, fft, sigma=grid.peak_width, **bounds)
    shift = (fixed.offset - box.offset + peak.shift) * VOXEL
    return shift, peak.peak, 1.0 - float(np.sum(moving * grid.block(box))), searched


def shell(rng, n, radius):
    """``n`` points on a bumpy closed surface of about ``radius`` (metres)."""
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return d * radius * (1.0 + 0.3 * np.sin(3 * d[:, :1]) * np.cos(2 * d[:, 1:2]))


@pytest.mark.parametrize("case", ["window", "anywhere", "scene"])
def test_the_law_correlation_is_the_papers_steps(case):
    rng = np.random.default_rng(4)
    model = shell(rng, 4000, 0.08)
    fixed = model
    if case == "scene":  # the object among others: the window is padded
        others = [shell(rng, 4000, 0.08) + offset
                  for offset in ([0.3, 0.0, 0.0], [-0.3, 0.1, 0.0], [0.0, 0.3, -0.1])]
        fixed = np.concatenate([model, *others])
    grid = TargetGrid(fixed, VOXEL, weighting="trilinear", peak_width=1.0, window=4,
                      max_memory=2e9)
    motion = np.array([0.0137, -0.0211, 0.0083])
    moved = model + motion
    centre = moved.mean(axis=0)
    radius = float(np.max(np.linalg.norm(moved - centre, axis=1)))
    around = None if case == "anywhere" else model.mean(axis=0) + [0.004, 0.0, -0.003]
    placed = grid.correlate(moved, radius, centre, around)
    shift, peak, cost, searched = reference(grid, moved, radius, centre, around)
    # each of the three paths: a window on its own FFT, anywhere, a padded window
    assert (searched is not None) == (case == "window")
    assert (grid.search_box(radius, around) is grid.box) == (case == "anywhere")
    np.testing.assert_allclose(placed.shift, shift, atol=1e-3 * VOXEL)
    assert placed.peak == pytest.approx(peak, abs=1e-5)
    assert placed.cost == pytest.approx(cost, abs=1e-6)
    # And the shift takes the moved points back, to the sub-voxel fit's accuracy.
    np.testing.assert_allclose(placed.shift, -motion, atol=0.1 * VOXEL)
    assert placed.peak > 0.5
