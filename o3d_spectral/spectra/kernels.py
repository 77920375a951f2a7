"""Compiled loops (numba) where numpy would make many passes over large temporaries.

Each kernel is a plain loop over its input, compiled on first use and cached on disk
(``cache=True``: later processes load it). The functions are pure and single-threaded,
and release the GIL (``nogil``): threads run them side by side; their callers check and
shape the arguments.

None is compiled with fast-math: the compiler vectorises their loops but neither reorders
nor fuses (FMA) their floating-point operations, so that they give the same bits on every
CPU, whatever its vector width (``tests/test_kernels.py`` compiles them for numba's
generic x86-64 target too). With fast-math the search's pose depended on the machine: the
240 occluded views of the seed-0 suite, registered on two 2-core machines, came back more
than a thousandth of a degree apart in 28 calls, four of them right on one machine and
wrong on the other. Without it the whitening of a 72x90x90 grid's spectrum takes 0.62
instead of 0.55 ms, the harmonic sums of 50,000 normals at bandwidth 16 4.7 instead of
3.0-3.7 ms.

Compiling them takes 6-9 s of CPU once after installation (most of it the batched
correlation's, whose transforms rocket-fft compiles in); loading them from the cache,
about 0.3 s in each process that uses them. ``python -m o3d_spectral.spectra.kernels``
(:func:`compile_all`) compiles them ahead, so that no registration pays for it.
"""

from __future__ import annotations

import numba
import numpy as np
import scipy.fft  # compiled into the batched correlation (rocket-fft)
from numpy.typing import NDArray

from .harmonic_kernels import harmonic_sums

__all__ = [
    "compile_all", "correlation_peaks_into", "splat_into", "turned_splat_into", "whitened",
    "whitened_into",
]


@numba.njit(cache=True, nogil=True)
def splat_into(grid: NDArray, u: NDArray, weights: NDArray, trilinear: bool,
               binary: bool) -> None:
    """Add each point's weight to ``grid`` (3D, zeroed by the caller) at the voxel
    holding it, or shared among the 8 voxel centres about it when ``trilinear``; with
    ``binary``, 1 in every voxel that receives weight (:func:`o3d_spectral.spectra.grid.splat`).

    Parameters
    ----------
    grid : ndarray, shape (X, Y, Z)
        Filled in place; points (corners) outside it are dropped.
    u : ndarray, shape (N, 3)
        Continuous voxel coordinates (voxel ``i`` spans ``[i, i + 1)``).
    weights : ndarray, shape (N,)
    trilinear, binary : bool
    """
    for i in range(u.shape[0]):
        _add_point(grid, u[i, 0], u[i, 1], u[i, 2], weights[i], trilinear, binary)


@numba.njit(cache=True, nogil=True)
def _add_point(grid: NDArray, ux: float, uy: float, uz: float, weight: float,
               trilinear: bool, binary: bool) -> None:
    """Add ``weight`` at the continuous voxel coordinates ``(ux, uy, uz)`` of ``grid``
    as :func:`splat_into` adds one point's."""
    nx, ny, nz = grid.shape
    half = 0.5 if trilinear else 0.0
    fx, fy, fz = ux - half, uy - half, uz - half
    bx, by, bz = int(np.floor(fx)), int(np.floor(fy)), int(np.floor(fz))
    ax, ay, az = fx - bx, fy - by, fz - bz
    corners = 2 if trilinear else 1
    for cx in range(corners):
        x = bx + cx
        if x < 0 or x >= nx:
            continue
        wx = (ax if cx else 1.0 - ax) if trilinear else 1.0
        for cy in range(corners):
            y = by + cy
            if y < 0 or y >= ny:
                continue
            wy = (ay if cy else 1.0 - ay) if trilinear else 1.0
            for cz in range(corners):
                z = bz + cz
                if z < 0 or z >= nz:
                    continue
                wz = (az if cz else 1.0 - az) if trilinear else 1.0
                w = weight * wx * wy * wz
                if binary:
                    if w != 0.0:
                        grid[x, y, z] = 1.0
                else:
                    grid[x, y, z] += w


@numba.njit(cache=True, nogil=True)
def turned_splat_into(
    grids: NDArray, points: NDArray, rotations: NDArray, offset: NDArray, normals: NDArray,
    viewpoint: NDArray, culled: bool, two_sided: bool, min_facing: int, trilinear: bool,
    binary: bool,
) -> None:
    """Turn points about a pivot by each of a stack of rotations and add them to the
    matching grid of a stack as :func:`splat_into` does, in one pass with no
    temporaries: for rotation ``R`` the point ``p`` (voxels, about the pivot) lands at
    ``u = R p + offset``, continuous voxel coordinates of its grid.

    With ``culled``, only the points whose turned normal ``R n`` faces ``viewpoint``
    (``R n . (viewpoint - u) > 0``; any non-zero cosine when ``two_sided``) are added,
    unless fewer than ``min_facing`` do, when every point is
    (:meth:`o3d_spectral.SpectralStepper.visible`).

    Parameters
    ----------
    grids : ndarray, shape (B, X, Y, Z)
        Filled in place (zeroed by the caller); points (corners) outside are dropped.
    points, normals : ndarray, shape (N, 3)
        Voxels about the pivot; unit normals (read only when ``culled``).
    rotations : ndarray, shape (B, 3, 3)
    offset, viewpoint : ndarray, shape (3,)
        The pivot and the sensor in the grid's voxel coordinates.
    culled, two_sided : bool
    min_facing : int
    trilinear, binary : bool
        As for :func:`splat_into`.
    """
    for b in range(rotations.shape[0]):
        _turned_splat(grids[b], points, rotations[b], offset, normals, viewpoint, culled,
                      two_sided, min_facing, trilinear, binary)


@numba.njit(cache=True, nogil=True)
def _turned_splat(
    grid: NDArray, points: NDArray, R: NDArray, offset: NDArray, normals: NDArray,
    viewpoint: NDArray, culled: bool, two_sided: bool, min_facing: int, trilinear: bool,
    binary: bool,
) -> None:
    """:func:`turned_splat_into` for one grid and one rotation ``R``."""
    n = points.shape[0]
    facing = np.ones(n, dtype=np.bool_)
    if culled:
        count = 0
        for i in range(n):
            p0, p1, p2 = points[i, 0], points[i, 1], points[i, 2]
            n0, n1, n2 = normals[i, 0], normals[i, 1], normals[i, 2]
            cosine = 0.0
            for a in range(3):
                turned = R[a, 0] * n0 + R[a, 1] * n1 + R[a, 2] * n2
                at = R[a, 0] * p0 + R[a, 1] * p1 + R[a, 2] * p2 + offset[a]
                cosine += turned * (viewpoint[a] - at)
            facing[i] = cosine != 0.0 if two_sided else cosine > 0.0
            count += facing[i]
        if count < min_facing:
            facing[:] = True
    for i in range(n):
        if facing[i]:
            p0, p1, p2 = points[i, 0], points[i, 1], points[i, 2]
            _add_point(grid, R[0, 0] * p0 + R[0, 1] * p1 + R[0, 2] * p2 + offset[0],
                       R[1, 0] * p0 + R[1, 1] * p1 + R[1, 2] * p2 + offset[1],
                       R[2, 0] * p0 + R[2, 1] * p1 + R[2, 2] * p2 + offset[2], 1.0,
                       trilinear, binary)


@numba.njit(cache=True, nogil=True)
def whitened_into(F: NDArray, G: NDArray, window: NDArray, eps: float, out: NDArray) -> None:
    """:func:`whitened` of each of a stack of spectra ``F`` (B, ..., 2) into ``out``
    (the same shape; may be ``F``)."""
    for b in range(F.shape[0]):
        whitened(F[b], G, window, eps, out[b])


@numba.njit(cache=True, nogil=True)
def whitened(F: NDArray, G: NDArray, window: NDArray, eps: float, out: NDArray) -> None:
    """``out = window G conj(F) / max(|G conj(F)|, eps |G_0 F_0|)``: the windowed,
    normalised cross-power spectrum of two spectra of non-negative grids
    (eq. cross_power_spectrum), in one pass.

    For a non-negative grid no frequency's magnitude exceeds the sum of its values, the
    zero frequency's ``F_0``: ``|G_0 F_0|`` is the largest cross-power term, the one the
    terms under ``eps`` of it are measured against
    (:func:`o3d_spectral.spectra.translation.cross_power_peak`).

    Parameters
    ----------
    F, G, out : ndarray, shape (..., 2)
        The moving and fixed half spectra and the result as the real and imaginary
        parts of each term (a complex array's ``view`` as reals, reshaped), one shape,
        C-contiguous; ``out`` may be ``F``.
    window : ndarray
        One real weight per term, of the spectra's precision.
    eps : float
        Of the spectra's precision.
    """
    f, g = F.reshape(-1, 2), G.reshape(-1, 2)
    w, o = window.ravel(), out.reshape(-1, 2)
    top2 = (f[0, 0] * f[0, 0] + f[0, 1] * f[0, 1]) * (g[0, 0] * g[0, 0] + g[0, 1] * g[0, 1])
    floor2 = eps * eps * top2
    if not floor2 > 0:
        floor2 = eps * eps
    for i in range(w.size):
        re = g[i, 0] * f[i, 0] + g[i, 1] * f[i, 1]  # g conj(f)
        im = g[i, 1] * f[i, 0] - g[i, 0] * f[i, 1]
        scale = w[i] / np.sqrt(max(re * re + im * im, floor2))
        o[i, 0] = re * scale
        o[i, 1] = im * scale


@numba.njit(cache=True, nogil=True)
def correlation_peaks_into(
    values: NDArray, index: NDArray, neighbours: NDArray, overlaps: NDArray, points: NDArray,
    rotations: NDArray, offset: NDArray, normals: NDArray, viewpoint: NDArray, culled: bool,
    two_sided: bool, min_facing: int, trilinear: bool, binary: bool, spectrum: NDArray,
    window: NDArray, eps: float, searched: NDArray, overlap: NDArray, overlap_at: NDArray,
    grids: NDArray, spectra: NDArray, correlations: NDArray,
) -> None:
    """The phase-correlation peak of a cloud turned by each of a stack of rotations
    against one fixed spectrum (eqs. cross_power_spectrum and fourier_shift_solution), a
    batch of grids at a time, the whole stack in one call outside the GIL.

    Each batch is turned and splatted (:func:`turned_splat_into`), transformed zero-padded
    to the FFT grid along the lines the moving grid reaches
    (:func:`o3d_spectral.spectra.fft.padded_forward`'s order of axes), whitened against
    ``spectrum`` (:func:`whitened_into`), transformed back (only the lines the searched
    block needs, as :func:`o3d_spectral.spectra.fft.cropped_inverse`, where it is smaller
    than the grid), and each grid's largest value
    within ``searched`` and its flat index (the first of equals in C order) read, with
    its six neighbours (for a sub-voxel fit) and the moving grid's inner product with
    ``overlap`` where it lies in it: the same values, to the bit, as those steps run one
    by one from NumPy.
    The transforms are pocketfft's, compiled in through rocket-fft, in place in the
    workspaces: nothing is allocated.

    Parameters
    ----------
    values : ndarray, shape (K,), float64
    index : ndarray, shape (K,), int64
        Filled: each rotation's peak (unscaled) and its flat index in the FFT grid.
    neighbours : ndarray, shape (K, 3, 2), float32
        Filled: the correlation one voxel before and after the peak along each axis
        (wrapping around the FFT grid; 0 outside the searched block).
    overlaps : ndarray, shape (K,), float64
        Filled: ``<g, overlap> / |g|`` of each turned moving grid ``g`` (0 for an empty
        grid), ``g``'s corner at ``overlap_at`` in ``overlap``; left as it is when
        ``overlap`` is empty.
    points, rotations, offset, normals, viewpoint, culled, two_sided, min_facing, \
trilinear, binary
        As for :func:`turned_splat_into`; ``rotations`` (K, 3, 3).
    spectrum : ndarray, shape (nx, ny, nz // 2 + 1), complex64
        The fixed grid's half spectrum on the FFT grid (nx, ny, nz).
    window : ndarray, shape (nx, ny, nz // 2 + 1), float32
    eps : float32
        As for :func:`whitened`.
    searched : ndarray, shape (3,), int64
        The peak is sought at indices below these per axis (the FFT grid's shape: all).
    overlap : ndarray, 3D or empty, float64
        A grid the moving grids are compared with before any shift, over the cells they
        share (the rest of each moving grid counts in its norm only).
    overlap_at : ndarray, shape (3,), int64
        The moving grid's corner in ``overlap``, cells (any, negative too).
    grids : ndarray, shape (B, mx, my, mz), float32
    spectra : ndarray, shape (B, nx, ny, nz // 2 + 1), complex64
    correlations : ndarray, shape (B, nx, ny, nz), float32
        Workspaces, overwritten: the batch's moving grids, their spectra and their
        correlations; ``B``, the grids transformed together.
    """
    mx, my, nz = grids.shape[1], grids.shape[2], correlations.shape[3]
    fixed = spectrum.view(np.float32)
    for start in range(0, rotations.shape[0], grids.shape[0]):
        count = min(grids.shape[0], rotations.shape[0] - start)
        block, out = grids[:count], spectra[:count]
        block[:] = 0.0
        turned_splat_into(block, points, rotations[start:start + count], offset, normals,
                          viewpoint, culled, two_sided, min_facing, trilinear, binary)
        np.fft.rfft(block, n=nz, axis=-1, out=out[:, :mx, :my, :])
        out[:, :mx, my:, :] = 0.0  # the zero padding
        out[:, mx:, :, :] = 0.0
        scipy.fft.fft(out[:, :mx], axis=2, overwrite_x=True)  # in place, as below
        scipy.fft.fft(out, axis=1, overwrite_x=True)
        reals = out.view(np.float32)
        whitened_into(reals, fixed, window, eps, reals)
        sx, sy = searched[0], searched[1]
        if sx < out.shape[1] or sy < out.shape[2]:  # only the lines the block needs
            scipy.fft.ifft(out, axis=1, overwrite_x=True)
            scipy.fft.ifft(out[:, :sx], axis=2, overwrite_x=True)
            np.fft.irfft(out[:, :sx, :sy], n=nz, axis=-1, out=correlations[:count, :sx, :sy])
        else:
            scipy.fft.ifftn(out, axes=(1, 2), overwrite_x=True)
            np.fft.irfft(out, n=nz, axis=-1, out=correlations[:count])
        grid = correlations[:count]
        for b in range(count):
            k = start + b
            values[k], index[k] = _peak_into(grid[b], searched, neighbours[k])
            if overlap.size:
                overlaps[k] = _normalised_inner(block[b], overlap, overlap_at)


@numba.njit(cache=True, nogil=True)
def _peak_into(grid: NDArray, searched: NDArray, neighbours: NDArray) -> tuple[float, int]:
    """The largest value of ``grid`` (3D) at indices below ``searched`` and its flat
    index (the first of equals in C order); ``neighbours`` (3, 2) filled with the values
    one voxel before and after it along each axis, wrapping around (0 outside the
    searched block: the grid may be computed only within it)."""
    best, at = grid[0, 0, 0], (0, 0, 0)
    for i in range(searched[0]):
        for j in range(searched[1]):
            for k in range(searched[2]):
                if grid[i, j, k] > best:
                    best, at = grid[i, j, k], (i, j, k)
    shape = grid.shape
    for axis in range(3):
        for side in range(2):
            i, j, k = at
            step = 2 * side - 1
            if axis == 0:
                i = (i + step) % shape[0]
            elif axis == 1:
                j = (j + step) % shape[1]
            else:
                k = (k + step) % shape[2]
            inside = i < searched[0] and j < searched[1] and k < searched[2]
            neighbours[axis, side] = grid[i, j, k] if inside else 0.0
    return best, (at[0] * shape[1] + at[1]) * shape[2] + at[2]


@numba.njit(cache=True, nogil=True)
def _normalised_inner(grid: NDArray, other: NDArray, at: NDArray) -> float:
    """``<grid, other> / |grid|`` (0 for an empty ``grid``) over the cells the two share,
    ``grid``'s corner at ``at`` in ``other``, summed in double precision in C order."""
    norm = 0.0
    g = grid.ravel()
    for i in range(g.size):
        value = np.float64(g[i])
        norm += value * value
    if not norm > 0.0:
        return 0.0
    ax, ay, az = at[0], at[1], at[2]
    inner = 0.0
    for x in range(max(-ax, 0), min(grid.shape[0], other.shape[0] - ax)):
        for y in range(max(-ay, 0), min(grid.shape[1], other.shape[1] - ay)):
            for z in range(max(-az, 0), min(grid.shape[2], other.shape[2] - az)):
                inner += np.float64(grid[x, y, z]) * other[x + ax, y + ay, z + az]
    return inner / np.sqrt(norm)


def compile_all() -> None:
    """Compile (or load from the cache) every kernel for the argument types the package
    passes: C-contiguous arrays (the fixed grid's of double precision; the correlation
    loop's of single precision, its inputs read only, as
    :func:`o3d_spectral.spectra.correlation_loop.correlation_peaks` passes them), each
    combination of the flags."""
    u, weights = np.zeros((1, 3)), np.ones(1)
    for trilinear in (False, True):
        for binary in (False, True):
            splat_into(np.zeros((2, 2, 2)), u, weights, trilinear, binary)
    harmonic_sums(np.array([[0.0, 0.0, 1.0]]), weights, 2)
    eye, origin, normals = np.eye(3), np.zeros(3), np.zeros((1, 3))
    cells = np.zeros((1, 2, 2, 2), dtype=np.float32)  # the batched correlation's grids
    for culled in (False, True):
        for trilinear in (False, True):
            for binary in (False, True):
                turned_splat_into(cells, u, eye[None], origin, normals, origin, culled, False,
                                  0, trilinear, binary)
    spectra = np.ones((1, 2, 2, 2), dtype=np.complex64).view(np.float32)
    whitened_into(spectra, spectra[0], cells[0], np.float32(1e-6), spectra.copy())
    from .correlation_loop import Splat, correlation_peaks  # as every caller calls it

    correlation_peaks(Splat.unculled(u, "trilinear"), eye[None],
                      np.ones((2, 2, 2), dtype=np.complex64),
                      np.ones((2, 2, 2), dtype=np.float32), 1e-6, (2, 2, 2),
                      np.zeros((2, 2, 2)), np.zeros(3, dtype=np.int64), batch=1,
                      moving_shape=(2, 2, 2), shape=(2, 2, 2))


if __name__ == "__main__":
    import time

    start = time.perf_counter()
    compile_all()
    print(f"o3d_spectral kernels ready in {time.perf_counter() - start:.1f} s")
