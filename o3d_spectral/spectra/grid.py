"""Voxel grids of point clouds (paper, eqs. voxel_index and voxel).

A :class:`Lattice` fixes the voxel size and the origin shared by every grid that will be
compared (the paper's requirement that both grids share one origin); a :class:`Box` is
an axis-aligned block of that lattice. Voxel ``(i, j, k)`` of a box covers the cube
whose centre is ``origin + (index + offset + 0.5) * voxel_size``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["Box", "Lattice", "splat", "SPLAT_MODES", "check_memory"]

SPLAT_MODES = ("trilinear", "count", "binary")


@dataclass(frozen=True)
class Lattice:
    """Infinite cubic lattice of voxels.

    Attributes
    ----------
    origin : ndarray, shape (3,)
        Corner of voxel (0, 0, 0), metres.
    voxel_size : float
        Edge of a voxel ``r``, metres.
    """

    origin: NDArray[np.float64]
    voxel_size: float

    def box_around(self, lower: ArrayLike, upper: ArrayLike, margin: int = 1) -> Box:
        """Smallest box holding the region ``[lower, upper]`` (metres) plus ``margin`` voxels."""
        lo = np.floor((np.asarray(lower) - self.origin) / self.voxel_size).astype(np.int64)
        hi = np.floor((np.asarray(upper) - self.origin) / self.voxel_size).astype(np.int64)
        return Box(self, lo - margin, tuple(int(n) for n in hi - lo + 1 + 2 * margin))


@dataclass(frozen=True)
class Box:
    """Block of ``shape`` voxels of a :class:`Lattice`, starting at lattice index ``offset``."""

    lattice: Lattice
    offset: NDArray[np.int64]
    shape: tuple[int, int, int]

    @property
    def corner(self) -> NDArray[np.float64]:
        """Position of the box's lowest corner, metres, shape (3,)."""
        return self.lattice.origin + self.offset * self.lattice.voxel_size

    def moved_to(self, offset: ArrayLike) -> Box:
        """The same-sized box at another lattice offset."""
        return Box(self.lattice, np.asarray(offset, dtype=np.int64), self.shape)


def check_memory(shape: tuple[int, ...], budget_bytes: float, what: str) -> None:
    """Raise ``ValueError`` when a float64 grid of ``shape`` (with its complex spectrum
    and FFT work buffers, about 4x) would exceed ``budget_bytes``."""
    need = 4.0 * 8.0 * float(np.prod(np.asarray(shape, dtype=np.float64)))
    if need > budget_bytes:
        raise ValueError(
            f"{what}: a grid of {shape[0]}x{shape[1]}x{shape[2]} voxels needs about "
            f"{need / 2**30:.1f} GiB, over the budget of {budget_bytes / 2**30:.1f} GiB; "
            "use a larger voxel_size, crop the clouds, or raise max_grid_memory "
            "(check the clouds are in metres)"
        )


def splat(
    points: ArrayLike,
    box: Box,
    *,
    mode: str = "trilinear",
    weights: ArrayLike | None = None,
    out: NDArray[np.float64] | None = None,
) -> NDArray[np.float64]:
    """Voxel grid ``f_t`` of a point set (paper, eq. voxel).

    Parameters
    ----------
    points : array_like, shape (N, 3)
        Metres.
    box : Box
        Grid geometry; points falling outside are dropped.
    mode : {"trilinear", "count", "binary"}
        ``"binary"``: 1 where a voxel holds a point (the paper's ``v_ijk``); ``"count"``:
        the (weighted) number of points per voxel; ``"trilinear"``: each point's weight
        shared among the 8 nearest voxel centres, which makes the grid a continuous
        function of the points' positions (sub-voxel phase correlation needs it).
    weights : array_like, shape (N,), optional
        Per-point mass (1 when omitted).
    out : ndarray, optional
        Array of at least ``box.shape`` to fill (zeroed first); the grid is written to
        its leading block, so a zero-padded FFT buffer can be passed directly.

    Returns
    -------
    ndarray
        ``out`` (or a new array of ``box.shape``).
    """
    from .kernels import splat_into  # numba: imported (and compiled) on first use

    if mode not in SPLAT_MODES:
        raise ValueError(f"mode must be one of {SPLAT_MODES}, got {mode!r}")
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    w = np.ones(len(p)) if weights is None else np.asarray(weights, dtype=np.float64)
    if w.shape != (len(p),):
        raise ValueError(f"weights must have shape ({len(p)},), got {w.shape}")
    grid = np.zeros(box.shape) if out is None else out
    grid.fill(0.0)
    u = (p - box.corner) / box.lattice.voxel_size  # continuous voxel coordinates
    block = grid[: box.shape[0], : box.shape[1], : box.shape[2]]
    splat_into(block, u, w, mode == "trilinear", mode == "binary")
    return grid
