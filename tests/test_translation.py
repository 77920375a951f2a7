import numpy as np
import pytest

from o3d_spectral.spectra.fft import RealFFT3, padded_forward
from o3d_spectral.spectra.grid import Lattice, splat
from o3d_spectral.spectra.translation import cross_power_peak, phase_correlation


@pytest.mark.parametrize("shift", [(0, 0, 0), (3, -5, 7), (-11, 0, 2), (15, 15, -16)])
def test_integer_shift_of_a_grid(shift, rng):
    f = np.zeros((32, 32, 32))
    f[8:20, 10:14, 5:25] = rng.random((12, 4, 20))
    g = np.roll(f, shift, axis=(0, 1, 2))
    estimate = phase_correlation(f, g)
    np.testing.assert_allclose(estimate.shift, shift, atol=1e-6)
    # 1 for a perfect shift, less the few frequencies too weak to whiten (eps)
    assert 0.99 < estimate.peak <= 1.0 + 1e-12


def test_random_subvoxel_shifts_of_a_point_cloud(rng):
    """Shifts of a cloud by random real amounts: within 0.1 voxel."""
    lattice = Lattice(np.zeros(3), 0.01)
    box = lattice.box_around([0.0, 0.0, 0.0], [0.5, 0.5, 0.5], margin=0)
    points = rng.normal(size=(3000, 3)) * [0.04, 0.03, 0.05] + 0.25
    f = splat(points, box)
    errors = []
    for _ in range(30):
        shift = rng.uniform(-0.1, 0.1, 3)  # metres: up to 10 voxels, any fraction
        estimate = phase_correlation(f, splat(points + shift, box))
        errors.append(np.abs(estimate.shift - shift / 0.01).max())
    assert max(errors) < 0.1


def test_sampled_gaussian_peak_is_located_exactly():
    """With a pure (Fourier) sub-voxel shift the Gaussian window makes the fit exact."""
    n = 48
    rng = np.random.default_rng(3)
    f = np.zeros((n, n, n))
    f[20:28, 18:30, 22:26] = rng.random((8, 12, 4))
    shift = np.array([2.3, -4.7, 0.45])
    nu = np.meshgrid(np.fft.fftfreq(n), np.fft.fftfreq(n), np.fft.rfftfreq(n), indexing="ij")
    ramp = np.exp(-2j * np.pi * sum(s * k for s, k in zip(shift, nu, strict=True)))
    g = np.fft.irfftn(np.fft.rfftn(f) * ramp, s=f.shape, axes=(0, 1, 2))
    np.testing.assert_allclose(phase_correlation(f, g, sigma=1.5).shift, shift, atol=0.02)


def test_asymmetric_unwrapping():
    """Grids zero-padded from their corners: shifts up to the fixed grid's size are read right."""
    fixed, moving, n = 40, 10, 50
    f = np.zeros((n, n, n))
    f[:moving, :moving, :moving] = np.random.default_rng(1).random((moving,) * 3)
    shift = (35, -8, 20)  # 35 > n / 2: wrongly read as -15 with a symmetric window
    g = np.roll(f, shift, axis=(0, 1, 2))
    fft = RealFFT3(f.shape)
    F, G = np.array(fft.forward(f)), np.array(fft.forward(g))
    estimate = cross_power_peak(F, G, fft, positive_below=(fixed, fixed, fixed))
    np.testing.assert_allclose(estimate.shift, shift, atol=1e-6)


@pytest.mark.parametrize("shift", [(0, 0, 0), (20, 3, 11), (7, 20, 0)])
def test_searched_shifts_keep_the_moving_grid_in_the_block(shift, rng):
    """A moving grid (20^3) zero-padded from the corner and a fixed block (40^3) holding
    it at ``shift``: read exactly, the searched range's edges included."""
    n, m = 40, 20
    pattern = rng.random((m, m, m))
    f, g = np.zeros((n, n, n)), np.zeros((n, n, n))
    f[:m, :m, :m] = pattern
    g[shift[0] : shift[0] + m, shift[1] : shift[1] + m, shift[2] : shift[2] + m] = pattern
    fft = RealFFT3(f.shape)
    F, G = np.array(fft.forward(f)), np.array(fft.forward(g))
    estimate = cross_power_peak(F, G, fft, searched=(n - m + 1,) * 3)
    np.testing.assert_allclose(estimate.shift, shift, atol=1e-6)
    assert estimate.peak > 0.9


def test_searched_peak_never_reads_a_wrapped_shift(rng):
    """The best match wraps around the block (shift 30 with a 20-voxel moving grid in 40):
    the peak is read inside the searched range only."""
    n, m = 40, 20
    f = np.zeros((n, n, n))
    f[:m, :m, :m] = rng.random((m, m, m))
    g = np.roll(f, (30, 0, 0), axis=(0, 1, 2))
    fft = RealFFT3(f.shape)
    F, G = np.array(fft.forward(f)), np.array(fft.forward(g))
    estimate = cross_power_peak(F, G, fft, searched=(n - m + 1,) * 3)
    assert np.all(estimate.shift >= 0) and np.all(estimate.shift <= n - m)
    assert estimate.peak < 0.5


def test_mismatched_grids_rejected():
    with pytest.raises(ValueError, match="one shape"):
        phase_correlation(np.zeros((4, 4, 4)), np.zeros((4, 4, 5)))


def test_fft_library_is_chosen_by_shape_and_both_transform_alike():
    """FFTW for sides that are all powers of two (or measured plans), pocketfft
    otherwise; either way the forward transform is numpy's and inverts exactly."""
    from o3d_spectral.spectra import fft

    if fft.pyfftw is not None:
        assert fft.backend((32, 64, 16)) == "pyfftw"
        assert fft.backend((30, 36, 36), planning="measure") == "pyfftw"
    assert fft.backend((30, 36, 36)) == "scipy"
    rng = np.random.default_rng(2)
    for shape in ((32, 64, 16), (30, 36, 35)):
        grid = rng.random(shape)
        plan = RealFFT3(shape)
        spectrum = np.array(plan.forward(grid))
        np.testing.assert_allclose(spectrum, np.fft.rfftn(grid), atol=1e-9 * grid.size)
        np.testing.assert_allclose(plan.inverse(spectrum), grid, atol=1e-12)


@pytest.mark.parametrize("shape", [(32, 64, 16), (30, 36, 35)])  # FFTW, pocketfft
def test_padded_and_cropped_transforms_are_those_of_the_whole_grid(shape, rng):
    plan = RealFFT3(shape)
    block = rng.random((11, 20, 9))
    grid = np.zeros(shape)
    grid[:11, :20, :9] = block
    spectrum = np.fft.rfftn(grid)
    np.testing.assert_allclose(padded_forward(block, shape), spectrum, atol=1e-9 * grid.size)
    whole = np.fft.irfftn(spectrum, s=shape, axes=(0, 1, 2))
    np.testing.assert_allclose(plan.inverse_cropped(spectrum, (7, 13, 5)), whole[:7, :13, :5],
                               atol=1e-12)
