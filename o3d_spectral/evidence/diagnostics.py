"""What a registration says about its inputs and result: warnings and notes, logged and
kept in the result.

A *warning* asks the caller to check something: the pose may be wrong, or an input was
not what the call expected. Each is logged on the ``o3d_spectral`` logger
(``logging.WARNING``) and appended to :attr:`o3d_spectral.SpectralRegistrationResult.warnings`:

- the control law stopped at ``max_iteration`` before converging;
- a cloud's given normals pointed to opposite sides between neighbours and were oriented
  again (an estimate with no orientation step);
- a cloud's normals are nearly all alike (a plane): its EGI leaves the rotation about
  them free;
- the returned pose may be wrong: its calibrated confidence
  (:mod:`o3d_spectral.evidence.confidence`) is under :data:`WARN_BELOW`;
- the returned pose is ambiguous: a distinct pose fits as well
  (:func:`o3d_spectral.evidence.verification.ambiguity`) and the source does not show that the
  two are one pose turned by its symmetry (it is a single view, or does not map onto
  itself by the turn between them);
- the returned pose is underdetermined: the clouds fit as well moved along a motion that
  the whole source resists (:mod:`o3d_spectral.evidence.free_motions`): the data do not fix the
  pose along it.

A *note* says how the call read the data or what the pose is free to be, with nothing to
check; each is logged at ``logging.INFO`` and appended to
:attr:`~o3d_spectral.SpectralRegistrationResult.notes`:

- a cloud was read two-sided: its neighbours' normals pointed away from each other (walls
  thinner than the points' spacing), and its surfaces are matched seen from either side;
- a distinct pose fits as well and is the returned one turned by a symmetry of the whole
  source (a model, not a view: a can's flip, a box's half turn): both are right;
- the pose's free motions that are a symmetry of the source
  (:mod:`o3d_spectral.evidence.free_motions`): the pose is right up to them.
"""

from __future__ import annotations

import logging
from typing import NamedTuple

from ..io.cloud import CloudReading
from .confidence import WARN_BELOW
from .constants import FLAT
from .free_motions import FreeMotion

__all__ = ["FLAT", "WARN_BELOW", "Messages", "may_be_wrong", "registration_messages"]

logger = logging.getLogger(__name__)


def may_be_wrong(confidence: float) -> bool:
    """Whether a result of calibrated confidence ``confidence`` is warned about: under
    :data:`WARN_BELOW` (the pose is more likely wrong than right)."""
    return confidence < WARN_BELOW


class Messages(NamedTuple):
    """A registration's warnings and notes (see the module docstring)."""

    warnings: list[str]
    notes: list[str]


def registration_messages(
    *, converged: bool, max_iteration: int, readings: dict[str, CloudReading],
    confidence: float | None, ambiguity: float | None = None,
    symmetric_rival: bool = False, free_motions: tuple[FreeMotion, ...] = (),
) -> Messages:
    """The warnings and notes of one registration, each logged once.

    Parameters
    ----------
    converged : bool
        The law met its convergence criteria.
    max_iteration : int
        The criteria's iteration budget.
    readings : dict of str to CloudReading
        How each cloud (``"source"``, ``"target"``) was read.
    confidence : float or None
        The returned pose's calibrated confidence (:mod:`o3d_spectral.evidence.confidence`);
        None: not measured.
    ambiguity : float or None
        The angle (degrees) to a distinct pose that fits as well, or None.
    symmetric_rival : bool
        That pose is the returned one turned by a symmetry of the whole source (not a
        single view).
    free_motions : tuple of FreeMotion
        The returned pose's free motions: a symmetry of the source is a note (of a single
        view's surface, one that says the object may not share it), any other a warning.
    """
    found, notes = [], []
    if not converged:
        found.append(f"the control law stopped at max_iteration={max_iteration} before "
                     "converging")
    for name, reading in readings.items():
        share = f"{100 * (reading.sign_disagreement or 0.0):.0f}%"
        if reading.normals_from == "re-oriented":
            found.append(
                f"{name}: {share} of neighbouring normals pointed to opposite sides (an "
                f"estimate with no orientation step?); they were oriented again "
                f"({reading.orientation}): pass consistently oriented normals, or "
                "CloudOption(camera_location=...)")
        if reading.two_sided:
            notes.append(
                f"{name}: {share} of neighbouring normals pointed to opposite sides, away "
                "from each other (walls thinner than the points' spacing, as a bowl's or a "
                "mug's): read two-sided, its surfaces matched as seen from either side "
                "(its EGI does not tell a wall's inside from its outside)")
        if reading.flatness >= FLAT:
            found.append(f"{name}: its normals are nearly all alike (a plane?): the "
                         "rotation about them is not constrained by its EGI")
    if confidence is not None and may_be_wrong(confidence):
        found.append(
            f"low confidence {confidence:.2f} (< {WARN_BELOW}): the pose may be wrong "
            "(result.confidence: the calibrated probability that it is right; "
            "result.pose_evidence says why)")
    if ambiguity is not None and symmetric_rival:
        notes.append(f"symmetric: a pose {ambiguity:.0f} deg away fits as well, the source "
                     "turned onto itself: both are right (result.ambiguity)")
    elif ambiguity is not None:
        found.append(f"ambiguous: a pose {ambiguity:.0f} deg away fits as well (a symmetric "
                     "object?): result.ambiguity, result.ambiguous_transformation")
    whole = readings["source"].view is None  # a view hides what may break its symmetry
    for motion in free_motions:
        if motion.symmetric and whole:
            notes.append(f"free: the clouds fit as well {motion.describe()}, a symmetry of "
                         "the source: the pose is right up to it (result.free_motions)")
        elif motion.symmetric:
            notes.append(f"free: the clouds fit as well {motion.describe()}, a symmetry of "
                         "the source as its view shows it: the pose is right up to it where "
                         "the object has that symmetry too (a can), not where a part out of "
                         "sight breaks it (a mug's handle) (result.free_motions)")
        else:
            found.append(f"underdetermined: the clouds fit as well {motion.describe()}, which "
                         "is no symmetry of the source: the data do not fix the pose along "
                         "it (result.free_motions)")
    for text in found:
        logger.warning(text)
    for text in notes:
        logger.info(text)
    return Messages(found, notes)
