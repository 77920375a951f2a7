"""Turns of a doubtful pose about the axis its inliers hold least.

A near-symmetric object (a mug: a body of revolution and a handle) shown by two views
from different sides has a pose that every spectral score prefers and that is wrong: the
view turned as if the camera had not moved, where the whole visible body overlaps and the
handle misses. The search's candidates all lead there, and the right turn is never
proposed. The pose's evidence tells it: its inliers carry almost none of the constraint
on one motion (:func:`o3d_spectral.evidence.pose.least_supported_motion`), a turn about
the body's axis that only the handle resists. Turning the pose about that axis in even
steps, polishing each turn briefly and measuring it as the confirmation does
(:func:`o3d_spectral.evidence.fit.fit`) proposes the turns the search could not.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from ..evidence.free_motions import turn_axis_point
from ..evidence.pose import Motion
from ..spectra import so3
from .constants import MAX_SUPPORT, MIN_ROTATION_SHARE, TURN_FINISHES

__all__ = ["Axis", "turn_axis", "turned", "holds_every_motion", "MIN_ROTATION_SHARE", "MAX_SUPPORT",
           "TURN_FINISHES"]


class Axis(NamedTuple):
    """A line: unit ``direction`` (3,) through ``point`` (3,, metres)."""

    direction: NDArray[np.float64]
    point: NDArray[np.float64]


def turn_axis(motion: Motion | None) -> Axis | None:
    """The axis of ``motion`` where it is a turn poorly held (:data:`MAX_SUPPORT`,
    :data:`MIN_ROTATION_SHARE`); None otherwise, or for no motion.

    A rotation ``w`` and a translation ``u`` of the centre ``c`` move ``p`` by
    ``w x (p - c) + u``: a turn about the line along ``w`` through
    ``c + w x u / |w|^2`` and a slide ``u . w / |w|`` along it. The motion is a turn
    where the turn (``|w|`` times the points' radius) is most of the two.
    """
    if motion is None or holds_every_motion(motion.share):
        return None
    rate = float(np.linalg.norm(motion.rotation))
    if rate == 0.0:
        return None
    direction = motion.rotation / rate
    turn, slide = rate * motion.radius, abs(float(motion.translation @ direction))
    if turn < MIN_ROTATION_SHARE * np.hypot(turn, slide):
        return None
    return Axis(direction, turn_axis_point(motion.rotation, motion.translation, motion.centre))


def holds_every_motion(support: float) -> bool:
    """Whether a pose's inliers carry over :data:`MAX_SUPPORT` of the constraint on the
    motion they resist least (``support``: a :class:`~o3d_spectral.evidence.pose.Motion`'s
    share, or ``PoseEvidence.motion_support``). A turn found by :func:`turned` is kept
    only where it resolves what made the search turn (the handle then lands on the
    handle): a turn that leaves a motion as poorly held only trades one doubtful pose for
    another."""
    return support > MAX_SUPPORT


def turned(pose: NDArray[np.float64], axis: Axis, count: int) -> list[NDArray[np.float64]]:
    """``pose`` (4, 4) followed by turns about ``axis`` by ``k * 360 / count`` degrees,
    ``k = 1 .. count - 1`` (4x4 each)."""
    return [so3.about_pivot(so3.exp(axis.direction * (2.0 * np.pi * k / count)), np.zeros(3),
                            axis.point) @ pose for k in range(1, count)]
