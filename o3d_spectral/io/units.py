"""Whether two clouds can be in the same units: a check of their extents.

A model in metres and a scan in millimetres differ in extent by 1000x, and nothing else
about them says so: every later message (a voxel size too large for one cloud, a grid too
large for the other) would point at the voxel size. :func:`check_same_units` refuses a
pair whose extents differ by :data:`MAX_EXTENT_RATIO` or more, naming both extents, their
ratio and the unit mix it suggests.

The refusal is an error, not a warning, because no voxel size registers such a pair even
when it is in one unit (a 3 cm object in a 5 m room, 170x): the smaller cloud must span
at least 4 voxels (and registers well at 18-44,
:data:`o3d_spectral.voxel.suggestion.VOXELS_ACROSS`),
so at 50x the larger cloud spans over 200 voxels (over 900 at 18), where placing an
object over a whole scene already failed at 175
(:data:`o3d_spectral.voxel.suggestion.MAX_VOXELS_ACROSS`)
and the grids outgrow the default memory budget. A small object in a scene registers
at the 10-40x of the real RGB-D frames; beyond, cropping the scene around the object does.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from .constants import MAX_EXTENT_RATIO, OUTLYING_SHARE, SPAN_POINTS

__all__ = ["MAX_EXTENT_RATIO", "UNIT_MIXES", "OUTLYING_SHARE", "SPAN_POINTS", "span",
           "check_same_units"]

#: Unit mixes, the one nearest the ratio of extents named when within a factor of 10 of
#: it (an object against a scene of it adds up to 10-40x): the factor, the smaller unit,
#: and the scale that brings it to metres.
UNIT_MIXES = ((1000.0, "millimetres", 0.001), (100.0, "centimetres", 0.01))


def span(points: ArrayLike) -> float:
    """The diagonal (metres) of the box holding ``points`` (N, 3) without the outermost
    :data:`OUTLYING_SHARE` of them at either end of each axis (measured on every k-th
    point of a cloud over :data:`SPAN_POINTS`)."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    p = p[:: max(len(p) // SPAN_POINTS, 1)]
    lower, upper = np.quantile(p, [OUTLYING_SHARE, 1.0 - OUTLYING_SHARE], axis=0)
    return float(np.linalg.norm(upper - lower))


def check_same_units(source: ArrayLike, target: ArrayLike) -> None:
    """``ValueError`` when the extents (:func:`span`) of the points ``source`` and
    ``target`` (N, 3 each, metres) differ by :data:`MAX_EXTENT_RATIO` or more: clouds in
    different units (a model in metres, a scan in millimetres), or a scene too large
    for the object to be found in it. The message names both extents, their ratio, the
    unit mix it suggests (:data:`UNIT_MIXES`) and both fixes. A cloud whose points all
    coincide (no extent) is left to the checks that refuse it by name.

    Examples
    --------
    >>> check_same_units(model_points, 1000.0 * model_points)  # doctest: +SKIP
    ValueError: source spans 0.187 m, target 187 m: 1000x; are they in the same units ...
    """
    spans = {"source": span(source), "target": span(target)}
    small, large = sorted(spans, key=spans.__getitem__)
    if not spans[small] > 0.0 or spans[large] < MAX_EXTENT_RATIO * spans[small]:
        return
    ratio = spans[large] / spans[small]
    mixes = [m for m in UNIT_MIXES if abs(np.log(ratio / m[0])) <= np.log(10.0)]
    likely = ""
    if mixes:
        factor, unit, scale = min(mixes, key=lambda m: abs(np.log(ratio / m[0])))
        likely = (f" {factor:.0f}x is {unit} against metres: if the {large} is in "
                  f"{unit}, scale it by {scale:g} (cloud.scale({scale:g}, center=(0, 0, 0)));")
    raise ValueError(
        f"source spans {spans['source']:.3g} m, target {spans['target']:.3g} m: "
        f"{ratio:.0f}x; are they in the same units (metres)?{likely} if the {small} is a "
        f"small object in a large scene, crop the {large} around it to under "
        f"{MAX_EXTENT_RATIO:.0f}x its size"
    )
