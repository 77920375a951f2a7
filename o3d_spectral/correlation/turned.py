"""The moving cloud as the batched correlation turns it: points about a pivot, in voxels."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..spectra.correlation_loop import Splat

__all__ = ["TurnedCloud", "WEIGHTINGS"]

#: How points fill a grid (:func:`o3d_spectral.spectra.grid.splat`'s modes).
WEIGHTINGS = ("trilinear", "count", "binary")


@dataclass(frozen=True, eq=False)
class TurnedCloud:
    """A cloud to be turned about a pivot and splatted on the moving grid.

    A rotation ``R`` puts point ``p`` at ``u = R p + offset``, in continuous voxel
    coordinates of the moving grid (voxel ``i`` spans ``[i, i + 1)``).

    Attributes
    ----------
    points : ndarray, shape (M, 3)
        About the pivot, voxels.
    offset : ndarray, shape (3,)
        Where the pivot lies on the moving grid, voxels.
    normals : ndarray, shape (M, 3), or None
        Unit normals, turned with the points, for culling; None: no culling.
    viewpoint : ndarray, shape (3,), or None
        The fixed cloud's sensor on the moving grid, voxels: only the points whose turned
        normal faces it are splatted (:meth:`o3d_spectral.SpectralStepper.visible`); None:
        every point.
    two_sided : bool
        Either side of a point faces the sensor (a non-zero cosine suffices).
    min_facing : int
        Fewer points facing the sensor than this: every point is splatted.
    weighting : {"trilinear", "count", "binary"}
        How points fill the grid.
    """

    points: NDArray[np.float64]
    offset: NDArray[np.float64]
    normals: NDArray[np.float64] | None = None
    viewpoint: NDArray[np.float64] | None = None
    two_sided: bool = False
    min_facing: int = 0
    weighting: str = "trilinear"

    def __post_init__(self) -> None:
        points = np.ascontiguousarray(self.points, dtype=np.float64).reshape(-1, 3)
        object.__setattr__(self, "points", points)
        object.__setattr__(self, "offset", np.asarray(self.offset, dtype=np.float64).reshape(3))
        if self.weighting not in WEIGHTINGS:
            raise ValueError(f"weighting must be one of {WEIGHTINGS}, got {self.weighting!r}")
        if (self.normals is None) != (self.viewpoint is None):
            raise ValueError("normals and viewpoint must be given together (culling) or not at all")
        if self.normals is not None:
            normals = np.ascontiguousarray(self.normals, dtype=np.float64).reshape(-1, 3)
            if normals.shape != points.shape:
                raise ValueError(f"normals must have shape {points.shape}, got {normals.shape}")
            object.__setattr__(self, "normals", normals)
            object.__setattr__(self, "viewpoint",
                               np.asarray(self.viewpoint, dtype=np.float64).reshape(3))

    @property
    def culled(self) -> bool:
        """Whether only the points facing :attr:`viewpoint` are splatted."""
        return self.viewpoint is not None

    @property
    def splat(self) -> Splat:
        """The compiled loop's arguments for this cloud (the points and offset stand in
        for the normals and viewpoint of a cloud that is not culled)."""
        normals = self.normals if self.culled else self.points
        viewpoint = self.viewpoint if self.culled else self.offset
        return Splat(self.points, self.offset, normals, viewpoint, self.culled, self.two_sided,
                     self.min_facing, self.weighting == "trilinear", self.weighting == "binary")
