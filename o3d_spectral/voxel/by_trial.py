"""A voxel size chosen by trial: registered at a few sizes about the rule's, the pose the
sizes agree on kept.

:func:`o3d_spectral.suggest_voxel_size` reads a size off the clouds' point spacing and
extent; on the benchmarks it registers as often as the sizes chosen by hand over all,
but less often on single groups (dragon scans 72-120 degrees apart, RGB-D crops of small
objects), where success turns on the size. :func:`voxel_trial` registers at the rule's
size and at the other sizes of :data:`VOXEL_LADDER` in turn, and stops where two sizes
agree on the pose.

One registration's calibrated ``result.confidence`` does not settle it: a pose wrong at
one size can be as confident as the right one at another (two sizes of a nearly
symmetric object both at 1.0; two scans 72 degrees apart at 0.92 wrong against 0.87 and
0.90 right), and the confidences of two sizes then rank the poses by noise. Two grids
of different sizes sample the clouds differently, so a pose found at both is rarely an
artefact of one. While sizes remain, two that agree on a pose (with a confidence of at
least 0.5) end the ladder. At its end the sizes vote: each for its pose with its
confidence, counted first where its pose is *decisive*: unambiguous (``result.ambiguity``
is None: no distinct pose fits as well at that size; an ambiguous result is one its own
evidence cannot tell from another pose) and not warned about. Its cost is two global
registrations where the first two sizes agree, ``len(ladder)`` otherwise.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..common.checks import real_array, shown
from ..evidence.diagnostics import may_be_wrong
from ..evidence.poses import distinct
from ..registration import registration_spectral_global
from ..result import SpectralRegistrationResult
from .constants import VOXEL_LADDER
from .suggestion import suggest_voxel_size

__all__ = ["VoxelTrial", "voxel_trial", "VOXEL_LADDER"]


@dataclass
class VoxelTrial:
    """The kept registration of :func:`voxel_trial` and what was tried.

    Attributes
    ----------
    voxel_size : float
        The kept registration's voxel size, metres.
    result : SpectralRegistrationResult
        The kept registration.
    tried : list of (float, float)
        Each size tried (metres) and its registration's ``confidence``, in order.
    agreed : bool
        Another size's pose agrees with the kept one (within 10 degrees,
        :func:`o3d_spectral.evidence.poses.distinct`).
    """

    voxel_size: float
    result: SpectralRegistrationResult
    tried: list[tuple[float, float]] = field(default_factory=list)
    agreed: bool = False


def voxel_trial(
    source: object, target: object, *, ladder: Sequence[float] = VOXEL_LADDER,
    **options: object,
) -> VoxelTrial:
    """Register ``source`` to ``target`` at a voxel size chosen by trial.

    The sizes are :func:`~o3d_spectral.suggest_voxel_size`'s times each factor of
    ``ladder``, in order, each registered by
    :func:`~o3d_spectral.registration_spectral_global`. While sizes remain, the ladder
    ends where a size's pose agrees with an earlier size's (the two are not
    :func:`~o3d_spectral.evidence.poses.distinct`: within 10 degrees) and the more confident
    of the two is not one the call warns may be wrong
    (:func:`o3d_spectral.evidence.diagnostics.may_be_wrong`, confidence under 0.5); the finer of the
    two that is not warned about is kept (the same pose, polished with correspondences
    nearer: two agreeing dragon scans 120 degrees apart, 0.90 confident at 7.2 mm and right,
    0.95 at 10.1 mm and 7 degrees off). Once every size is tried, the sizes vote: the poses
    that agree with each pose form its pool, scored by the sum of the confidences of its
    *decisive* poses (no distinct pose fitting as well at their size, ``result.ambiguity``
    None, and not warned about), ties by the sum of all its confidences; the most confident
    pose of the best pool is kept (the first of equals).

    Parameters
    ----------
    source, target : PointCloud, tensor PointCloud or ndarray
        As for :func:`~o3d_spectral.registration_spectral_global` (metres).
    ladder : sequence of float
        Positive factors of the rule's size, the first tried first.
    **options
        Keyword arguments of :func:`~o3d_spectral.registration_spectral_global`
        (``option``, ``search``, ``cloud``, ``refinement``, ...), the same at every size.

    Returns
    -------
    VoxelTrial

    Raises
    ------
    TypeError
        For a ``ladder`` that is not a sequence of real numbers (``None``, a string).
    ValueError
        For an empty ``ladder`` or a factor that is not a positive number, and as
        :func:`~o3d_spectral.suggest_voxel_size` and the registration call.

    Notes
    -----
    The coarser size costs a median 0.6 of the rule's registration and the finer 1.6
    times it, so a call costs about 1.6 times the rule's where the first two sizes agree
    and 3.2 times otherwise (on the benchmarks a median 1.8 times per case, three sizes
    in two cases of five: an object with a symmetry is often placed right at two sizes
    by two of its symmetric poses, which do not agree). ``--voxel-size rule`` (one
    registration at the rule's size) is the fast path.

    Examples
    --------
    >>> trial = o3d_spectral.voxel_trial(model, scan)  # doctest: +SKIP
    >>> trial.voxel_size, trial.result.confidence, trial.agreed  # doctest: +SKIP
    """
    factors = real_array("ladder", ladder)  # TypeError for None, strings, objects
    if factors.ndim != 1 or not factors.size or not np.all(np.isfinite(factors) & (factors > 0)):
        raise ValueError(f"ladder must be a sequence of positive factors, got {shown(ladder)}")
    rule = suggest_voxel_size(source, target)
    trials: list[VoxelTrial] = []
    for factor in factors.tolist():
        voxel_size = rule * factor
        trials.append(VoxelTrial(voxel_size, registration_spectral_global(
            source, target, voxel_size, **options)))
        kept = _settled(trials) if len(trials) < len(factors) else None
        if kept is not None:
            break
    else:
        kept = _voted(trials)
    kept.tried = [(t.voxel_size, t.result.confidence) for t in trials]
    kept.agreed = any(_agree(kept, t) for t in trials if t is not kept)
    return kept


def _settled(trials: Sequence[VoxelTrial]) -> VoxelTrial | None:
    """Of the last trial and an earlier one whose pose it agrees with, the finer that the
    call does not warn may be wrong; None where there is none."""
    *earlier, last = trials
    settled = []
    for other in (other for other in earlier if _agree(other, last)):
        unwarned = [t for t in (other, last) if not may_be_wrong(t.result.confidence)]
        if unwarned:
            settled.append(min(unwarned, key=lambda t: t.voxel_size))
    return _best(settled) if settled else None


def _agree(a: VoxelTrial, b: VoxelTrial) -> bool:
    """Whether two trials' poses agree: their rotations are not distinct."""
    return not distinct(np.asarray(a.result.transformation),
                        np.asarray(b.result.transformation))


def _best(trials: Sequence[VoxelTrial]) -> VoxelTrial:
    """The most confident of ``trials``, the first of equals."""
    return max(trials, key=lambda t: t.result.confidence)


def _decisive(trial: VoxelTrial) -> bool:
    """Whether a trial's pose is unambiguous (no distinct pose fits as well at its size)
    and not one the call warns may be wrong."""
    return trial.result.ambiguity is None and not may_be_wrong(trial.result.confidence)


def _voted(trials: Sequence[VoxelTrial]) -> VoxelTrial:
    """The most confident trial of the best-scoring pool of agreeing trials."""
    def score(pool: list[VoxelTrial]) -> tuple[float, float]:
        confidences = [t.result.confidence for t in pool]
        decisive = [t.result.confidence for t in pool if _decisive(t)]
        return sum(decisive), sum(confidences)

    pools = [[other for other in trials if _agree(trial, other)] for trial in trials]
    return _best(max(pools, key=score))
