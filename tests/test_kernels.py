import os
import subprocess
import sys
from pathlib import Path

import pytest


@pytest.mark.slow
def test_kernels_compile_ahead_from_the_command_line():
    """``python -m o3d_spectral.spectra.kernels`` compiles (or loads) every kernel and says so."""
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    done = subprocess.run([sys.executable, "-m", "o3d_spectral.spectra.kernels"],
                          capture_output=True, text=True, env=env, timeout=300)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("o3d_spectral kernels ready in ")


@pytest.mark.slow
def test_compiling_ahead_covers_the_types_the_correlation_passes():
    """After ``compile_all`` a batched correlation with every output (peaks, neighbours,
    overlaps) and a single correlation (the law's, on the fixed grid's cached spectrum)
    compile nothing more: the first registration does not pay for it."""
    code = (
        "import numpy as np\n"
        "from o3d_spectral.spectra import kernels\n"
        "from o3d_spectral.correlation import BatchedCorrelation, TurnedCloud\n"
        "kernels.compile_all()\n"
        "ahead = {k: set(f.signatures) for k, f in vars(kernels).items()\n"
        "         if hasattr(f, 'signatures')}\n"
        "cloud = TurnedCloud(np.random.default_rng(0).uniform(-4, 4, (50, 3)), [6.0] * 3)\n"
        "fixed = BatchedCorrelation.grid_of(cloud, (12, 12, 12))\n"
        "for overlap in (None, fixed):\n"
        "    BatchedCorrelation(fixed, (12, 12, 12), overlap=overlap).peaks(\n"
        "        cloud, np.eye(3)[None])\n"
        "from o3d_spectral.spectra.target_grid import TargetGrid\n"
        "grid = TargetGrid(cloud.points, 1.0, weighting='trilinear', peak_width=1.0,\n"
        "                  window=4, max_memory=1e9)\n"
        "grid.correlate(cloud.points + 0.5, 4.0 * 3**0.5, np.zeros(3), around=[0.5] * 3)\n"
        "later = {k: set(f.signatures) - ahead[k] for k, f in vars(kernels).items()\n"
        "         if hasattr(f, 'signatures')}\n"
        "print({k: len(v) for k, v in later.items() if v})\n"
    )
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=env, timeout=300)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "{}"


#: Every kernel's floating-point output, as one digest, from one process.
_KERNEL_DIGEST = """
import hashlib
import numpy as np
from o3d_spectral.spectra import kernels, so3
from o3d_spectral.spectra.correlation_loop import Splat, correlation_peaks
rng = np.random.default_rng(5)
digest = hashlib.sha256()
directions = rng.normal(size=(700, 3))
directions /= np.linalg.norm(directions, axis=1, keepdims=True)
digest.update(kernels.harmonic_sums(directions, rng.uniform(size=700), 12).tobytes())
shape = (16, 16, 9)
moving = (rng.normal(size=(2, *shape, 2))).astype(np.float32)
fixed = (rng.normal(size=(*shape, 2))).astype(np.float32)
window = rng.uniform(size=shape).astype(np.float32)
out = np.empty_like(moving)
kernels.whitened_into(moving, fixed, window, np.float32(1e-6), out)
digest.update(out.tobytes())
points = rng.uniform(-5.0, 5.0, (400, 3))
normals = rng.normal(size=(400, 3))
normals /= np.linalg.norm(normals, axis=1, keepdims=True)
rotations = np.stack([so3.exp(rng.normal(size=3)) for _ in range(3)])
spectrum = np.fft.rfftn(rng.uniform(size=(32, 32, 32))).astype(np.complex64)
splat = Splat(points, np.full(3, 8.0), normals, np.array([30.0, 8.0, 8.0]), True, False,
              10, True, False)
for found in correlation_peaks(splat, rotations, spectrum, np.ones((32, 32, 17), np.float32),
                               1e-6, (32, 32, 32), rng.uniform(size=(20, 20, 20)),
                               np.array([-3, 2, 1]), batch=2, moving_shape=(16, 16, 16),
                               shape=(32, 32, 32)):
    digest.update(np.ascontiguousarray(found).tobytes())
print(digest.hexdigest())
"""


@pytest.mark.slow
def test_the_kernels_give_the_same_bits_on_any_cpu(tmp_path):
    """The compiled kernels (harmonic sums, whitening, the turned and culled splat, the
    batched correlation with its neighbours and overlaps) give the same bits compiled
    for this CPU as for numba's generic x86-64 one (no SIMD beyond SSE2, no FMA): the
    compiler may vectorise but not reorder or fuse their floating-point operations, so
    that a registration's pose does not depend on the machine's instruction set."""
    root = str(Path(__file__).resolve().parents[1])

    def digest(**variables):
        env = {**os.environ, "PYTHONPATH": root, **variables}
        done = subprocess.run([sys.executable, "-c", _KERNEL_DIGEST], capture_output=True,
                              text=True, env=env, timeout=600)
        assert done.returncode == 0, done.stderr
        return done.stdout.strip()

    host = digest(NUMBA_CACHE_DIR=str(tmp_path / "host"))
    assert len(host) == 64
    assert digest(NUMBA_CPU_NAME="generic", NUMBA_CACHE_DIR=str(tmp_path / "generic")) == host


@pytest.mark.parametrize("culled", [False, True])
@pytest.mark.parametrize("cropped", [False, True])
def test_the_compiled_correlation_is_its_steps_to_the_bit(culled, cropped):
    """``correlation_peaks_into`` gives, to the bit, the peaks of its steps run one by one
    from NumPy (the compiled splat, pocketfft through ``scipy.fft``, the compiled
    whitening; within a searched block, the inverse transform of only the lines it
    needs), whatever the batch: each peak within the searched block, its neighbours
    (wrapping around, 0 outside the block), and each moving grid's overlap with a fixed
    one in double precision."""
    import numpy as np
    import scipy.fft

    from o3d_spectral.spectra import so3
    from o3d_spectral.spectra.fft import padded_forward
    from o3d_spectral.spectra.kernels import (
        correlation_peaks_into,
        turned_splat_into,
        whitened_into,
    )

    rng = np.random.default_rng(3)
    points = rng.uniform(-5.0, 5.0, (200, 3))
    normals = rng.normal(size=(200, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    offset, viewpoint = np.full(3, 7.0), np.array([7.0, 7.0, 40.0])
    moving, shape = (14, 14, 14), (30, 27, 32)
    searched = (9, 20, 4) if cropped else shape
    rotations = so3.uniform_rotations(7)
    flags = (culled, False, 20, True, False)
    fixed = np.zeros((1, 16, 14, 18), dtype=np.float32)
    turned_splat_into(fixed, points + 1.5, np.eye(3)[None], offset, normals, viewpoint, *flags)
    spectrum = padded_forward(fixed, shape)[0].astype(np.complex64)
    window = rng.uniform(0.5, 1.0, spectrum.shape).astype(np.float32)
    eps = np.float32(1e-6)
    overlap = rng.uniform(0.0, 1.0, (20, 12, 17))  # the moving grid astride its edges
    overlap_at = np.array([-2, 3, 1])
    padded = np.zeros((40, 40, 40))
    padded[10:30, 10:22, 10:27] = overlap
    on_moving = padded[8:22, 13:27, 11:25]  # 10 + overlap_at onwards, the moving shape

    grids = np.zeros((len(rotations), *moving), dtype=np.float32)
    turned_splat_into(grids, points, rotations, offset, normals, viewpoint, *flags)
    spectra = padded_forward(grids, shape).astype(np.complex64)
    reals = spectra.view(np.float32)
    whitened_into(reals, spectrum.view(np.float32), window, eps, reals)
    if cropped:  # only the lines the searched block needs, one axis at a time
        lines = scipy.fft.ifft(scipy.fft.ifft(spectra, axis=1)[:, : searched[0]], axis=2)
        correlations = np.zeros((len(rotations), *shape), dtype=np.float32)
        correlations[:, : searched[0], : searched[1]] = scipy.fft.irfft(
            lines[:, :, : searched[1]], n=shape[2], axis=-1)
    else:
        scipy.fft.ifftn(spectra, axes=(1, 2), overwrite_x=True)
        correlations = scipy.fft.irfft(spectra, n=shape[2], axis=-1)
    block = correlations[:, : searched[0], : searched[1], : searched[2]]
    at = np.stack(np.unravel_index(np.argmax(block.reshape(len(rotations), -1), axis=1),
                                   block.shape[1:]), axis=-1)
    expected_values = block.reshape(len(rotations), -1).max(axis=1)
    expected_index = np.ravel_multi_index(at.T, shape)
    inside = np.zeros(correlations.shape, dtype=bool)
    inside[:, : searched[0], : searched[1], : searched[2]] = True
    expected_neighbours = np.stack([np.stack(
        [np.roll(np.where(inside, correlations, 0), -step, axis=1 + axis)[
            (np.arange(len(rotations)), *at.T)] for step in (-1, 1)], axis=-1)
        for axis in range(3)], axis=1)
    flat = grids.reshape(len(rotations), -1).astype(np.float64)
    expected_overlaps = flat @ on_moving.ravel() / np.linalg.norm(flat, axis=1)
    for batch in (1, 3, 7, 50):  # workspaces left dirty by the batch before
        workspaces = (np.full((batch, *moving), 9.0, dtype=np.float32),
                      np.full((batch, *spectrum.shape), 9.0, dtype=np.complex64),
                      np.full((batch, *shape), 9.0, dtype=np.float32))
        values, index = np.zeros(len(rotations)), np.zeros(len(rotations), dtype=np.int64)
        neighbours = np.zeros((len(rotations), 3, 2), dtype=np.float32)
        overlaps = np.zeros(len(rotations))
        correlation_peaks_into(values, index, neighbours, overlaps, points, rotations, offset,
                               normals, viewpoint, *flags, spectrum, window, eps,
                               np.array(searched), overlap, overlap_at, *workspaces)
        np.testing.assert_array_equal(values, expected_values)
        np.testing.assert_array_equal(index, expected_index)
        np.testing.assert_array_equal(neighbours, expected_neighbours)
        np.testing.assert_allclose(overlaps, expected_overlaps, rtol=1e-12)


def test_each_thread_keeps_its_workspaces_within_a_count_and_a_size(monkeypatch):
    """A thread gets back the workspaces it used for a size (nothing allocated again),
    keeps at most WORKSPACES sizes and WORKSPACE_BYTES, the size asked for always, and
    never shares them with another thread (each check in a fresh thread, which starts
    with none)."""
    import threading

    from o3d_spectral.spectra import correlation_loop as loop

    def fresh(check):
        failed = []

        def run():
            try:
                check()
            except AssertionError as error:
                failed.append(error)

        thread = threading.Thread(target=run)
        thread.start()
        thread.join()
        if failed:
            raise failed[0]

    def count():
        first = loop.workspaces(2, (4, 4, 4), (8, 8, 8))
        assert loop.workspaces(2, (4, 4, 4), (8, 8, 8)) is first
        assert [a.shape for a in first] == [(2, 4, 4, 4), (2, 8, 8, 5), (2, 8, 8, 8)]
        for n in range(loop.WORKSPACES):
            loop.workspaces(1, (4, 4, 4), (9 + n, 8, 8))
        assert loop.workspaces(2, (4, 4, 4), (8, 8, 8)) is not first  # the oldest dropped

    def size():
        small = loop.workspaces(1, (4, 4, 4), (8, 8, 8))
        huge = loop.workspaces(1, (4, 4, 4), (32, 32, 32))  # over the budget alone: kept
        assert loop.workspaces(1, (4, 4, 4), (32, 32, 32)) is huge
        assert loop.workspaces(1, (4, 4, 4), (8, 8, 8)) is not small  # dropped for it

    fresh(count)
    mine = loop.workspaces(2, (4, 4, 4), (8, 8, 8))
    theirs = []
    fresh(lambda: theirs.append(loop.workspaces(2, (4, 4, 4), (8, 8, 8))))
    assert theirs[0][0] is not mine[0]
    monkeypatch.setattr(loop, "WORKSPACE_BYTES", 10_000)  # about one 8^3 set
    fresh(size)
