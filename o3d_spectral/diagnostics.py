"""Warnings about a registration's inputs and result, logged and kept in the result.

Each warning is logged on the ``o3d_spectral`` logger (``logging.WARNING``) and appended
to :attr:`o3d_spectral.SpectralRegistrationResult.warnings`:

- the control law stopped at ``max_iteration`` before converging;
- a cloud's given normals pointed to opposite sides between neighbours and were oriented
  again (an estimate with no orientation step);
- a cloud was read two-sided: its neighbours' normals pointed away from each other (walls
  thinner than the points' spacing), and its surfaces are matched seen from either side;
- a cloud's normals are nearly all alike (a plane): its EGI leaves the rotation about
  them free;
- the returned pose fits the target poorly, or a distinct pose the search found fits it
  clearly better (:func:`low_fit`).
"""

from __future__ import annotations

import logging

from .io.cloud import CloudReading

__all__ = ["FLAT", "LOW_FIT", "RIVAL_LEAD", "low_fit", "registration_warnings"]

logger = logging.getLogger(__name__)

#: A cloud whose mean unit normal is at least this long is flat (:attr:`CloudReading.flatness`).
FLAT = 0.97
#: The failure signal's constants, chosen on the runs of ``eval/voxel_advice.py`` (the
#: four suites, 96 instances each, and the real groups from 4 rotations each, at the
#: hand-chosen voxel sizes: 508 calls, 80 wrong): among fits of 0.5-0.7 and leads of
#: 0-0.2, the pair whose flags are most often right of those that flag at least as many
#: wrong poses as Open3D's ``fitness`` under 0.5 (32% of its flags are wrong poses, 70% of
#: the wrong poses are flagged; ``fitness`` under 0.5: 29%, 69%; each half of the runs
#: alike).
#: docs/results.md has the table.
#:
#: A result whose fit (``result.fit``) is under this is flagged. Right poses of whole and
#: partial views fit 0.9-1.0; a model right on a view that leaves part of it out (an
#: occluder the view does not hold) fits 0.4-0.8, as wrong ones do; so does a right pose
#: between two scans that share little.
LOW_FIT = 0.7
#: A result is flagged too when a distinct pose the search found fits better than it by
#: this much (a box turned half a turn fits as well as the right pose: no lead, no flag).
RIVAL_LEAD = 0.05


def low_fit(fit: float, rival_fit: float = 0.0) -> bool:
    """Whether a result of fit ``fit`` whose best distinct rival fits ``rival_fit`` (see
    :class:`o3d_spectral.SpectralRegistrationResult`) is flagged: ``fit`` under
    :data:`LOW_FIT`, or ``rival_fit`` over ``fit`` by :data:`RIVAL_LEAD` or more."""
    return fit < LOW_FIT or rival_fit - fit >= RIVAL_LEAD


def registration_warnings(
    *, converged: bool, max_iteration: int, readings: dict[str, CloudReading],
    fit: float | None, rival_fit: float = 0.0,
) -> list[str]:
    """The warnings of one registration, each logged once.

    Parameters
    ----------
    converged : bool
        The law met its convergence criteria.
    max_iteration : int
        The criteria's iteration budget.
    readings : dict of str to CloudReading
        How each cloud (``"source"``, ``"target"``) was read.
    fit : float or None
        The returned pose's fit (:mod:`o3d_spectral.verification`); None: not measured.
    rival_fit : float
        The best fit of a distinct pose the search found (0 when none).
    """
    found = []
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
            found.append(
                f"{name}: {share} of neighbouring normals pointed to opposite sides, away "
                "from each other (walls thinner than the points' spacing, as a bowl's or a "
                "mug's): read two-sided, its surfaces matched as seen from either side "
                "(its EGI does not tell a wall's inside from its outside)")
        if reading.flatness >= FLAT:
            found.append(f"{name}: its normals are nearly all alike (a plane?): the "
                         "rotation about them is not constrained by its EGI")
    if fit is not None and low_fit(fit, rival_fit):
        found.append(
            f"low fit {fit:.2f} (< {LOW_FIT}): only {fit:.0%} of the source points the "
            "target could show lie within a voxel of it: the pose may be wrong (result.fit; "
            "try another voxel size)" if fit < LOW_FIT else
            f"low fit {fit:.2f} against {rival_fit:.2f} for a distinct pose the search "
            "found: the pose may be wrong (result.fit, result.rival_fit)")
    for text in found:
        logger.warning(text)
    return found
