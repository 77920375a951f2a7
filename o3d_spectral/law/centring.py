"""Clouds are registered in a frame centred on the target, wherever they lie.

The calls move both clouds by minus the target's centroid, register them there, and
express every result in the caller's frame again, so that the result does not depend on
where the caller's frame has its origin: the voxel grids' lattice
(:class:`o3d_spectral.spectra.target_grid.TargetGrid` aligns it to multiples of the voxel size)
then sits in the same place on the clouds whether they are 1 m or 1000 km from the
origin, and georeferenced coordinates (UTM, hundreds of kilometres) lose no precision.
What the origin of the caller's frame means (the sensor of a scan in its sensor's frame)
is kept: the stepper is told where it went (``frame_origin``), and sensor positions
given in options are moved with the clouds.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import NDArray

from ..io.cloud import CloudArrays
from ..options import CloudOption
from .constants import CENTRE_DISTANCE
from .loop import IterationRecord

__all__ = ["CENTRE_DISTANCE", "offset", "shifted", "centred_arrays", "centred_option",
           "uncentred_history"]


def offset(target: CloudArrays) -> NDArray[np.float64] | None:
    """The target's centroid when over ``CENTRE_DISTANCE`` from the origin, else None
    (only a target centred exactly on the origin already)."""
    centroid = target.points.mean(axis=0)
    return centroid if np.linalg.norm(centroid) > CENTRE_DISTANCE else None


def shifted(transformation: NDArray[np.float64], c: NDArray[np.float64]) -> NDArray[np.float64]:
    """The rigid motion ``transformation`` (4, 4) in coordinates ``x - c`` (metres);
    ``shifted(M, -c)`` undoes ``shifted(M, c)``."""
    out = np.array(transformation, dtype=np.float64)
    out[:3, 3] += out[:3, :3] @ c - c
    return out


def centred_arrays(arrays: CloudArrays, c: NDArray[np.float64]) -> CloudArrays:
    """``arrays`` with its points moved by ``-c`` (normals unchanged)."""
    return CloudArrays(arrays.points - c, arrays.normals)


def centred_option(cloud: CloudOption, c: NDArray[np.float64]) -> CloudOption:
    """``cloud`` with its sensor positions moved by ``-c`` ("auto" stays "auto": the
    stepper is told where the caller's origin went)."""
    changes = {}
    for name in ("camera_location", "source_camera_location"):
        if getattr(cloud, name) is not None:
            changes[name] = tuple(np.asarray(getattr(cloud, name)) - c)
    if cloud.target_viewpoint is not None and not isinstance(cloud.target_viewpoint, str):
        changes["target_viewpoint"] = tuple(np.asarray(cloud.target_viewpoint) - c)
    return dataclasses.replace(cloud, **changes)


def uncentred_history(
    history: list[IterationRecord], c: NDArray[np.float64]
) -> list[IterationRecord]:
    """The records of a registration made in coordinates ``x - c``, in the caller's frame
    (the law's rotation and translation about the centroid do not change)."""
    return [
        dataclasses.replace(
            record, transformation=shifted(record.transformation, -c), centre=record.centre + c
        )
        for record in history
    ]
