"""Early confirmation of the search's best placed hypothesis: stop where it is clear.

The global search places the rotation correlation's peaks by phase correlation
(:mod:`o3d_spectral.search.placement`); on most calls the best placed one is
already right and the law's climbs only refine it. :func:`confirm` tells those calls
apart before the climbs run, the way RANSAC stops once a hypothesis is verified:

1. the best placed hypothesis is polished by a short point-to-plane ICP (a pass at two
   voxels, then one at one voxel) of the moving cloud's one-point-per-voxel points that
   the fixed cloud's sensor would see there, against the fixed cloud near that pose;
2. its *fit* is the share of those points within one voxel of the fixed cloud after the
   polish (Open3D's ``fitness`` on the visible points), and its *closeness* the share
   within a quarter voxel (:data:`CLOSE_DISTANCE`) of the fixed surface's tangent plane
   at their nearest point (the fixed cloud is thinned to half-voxel cells: the plane,
   not the spacing of its points, says how close the surfaces are);
3. the next placed hypotheses are polished and measured the same way; those whose
   polished pose is :func:`~o3d_spectral.search.poses.distinct` from the best's are its
   rivals (a start that the polish brings to the same pose is none).

The pose is confirmed when its fit reaches :data:`MIN_FIT` (enough of the cloud is
there) and no rival lies closer to the fixed cloud; never in a scene
(:class:`~o3d_spectral.search.situation.Kind`: there a flat face fits a table or a box
beside the object as well as the object itself, and the places not climbed yet are not
compared).
The two scales do two jobs. At one voxel a surface turned by a near-symmetry of the
object (a box turned half a turn, a can about its axis) still lies within a voxel of
itself, so the fit tells whether the cloud is there but not which of those poses is
right; at a quarter voxel the polished right pose leaves the noise only, a near-symmetric
one the object's small asymmetries. A rival as close as the best is then a symmetry at
the scale the data can tell, and either pose is right. Both numbers are calibrated for
precision, not for the share of calls that stop (``eval/bench_speed.py`` reports both on
every group): a view that does not show what tells two poses apart (a mug's handle) is
never confirmed, since a distinct alternative then fits as closely, and the whole search
runs.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import open3d as o3d
from numpy.typing import NDArray

from ..io.rows import lengths
from ..parallel import resolved_workers, thread_map
from ..refinement import near_pose, point_to_plane_icp
from ..stepper import MovingCloud, SpectralStepper
from .placement import Hypothesis
from .poses import distinct

__all__ = ["Confirmation", "Fit", "confirm", "fit", "closer", "MIN_FIT",
           "CLOSE_DISTANCE", "CLOSER_MARGIN", "CANDIDATES", "ICP_DISTANCES", "FIXED_CELL"]

#: Calibrated constants: the short polish's fit and closeness of the three best placed
#: hypotheses and whether each was right (within 5 degrees and 1 cm, symmetry-aware), on
#: instances 0-47 of each view suite and two rotations of each dragon pair, checked on
#: instances 48-143 and four rotations; rules chosen for no wrong early stop, with
#: headroom (``eval/bench_speed.py`` reports the early stops and the wrong ones among them
#: on every group).
#:
#: Least fit of a confirmed pose. Wrong poses of occluded views fit up to 0.70 (a view
#: half hidden leaves a model turned a quarter or half a turn as much surface to match);
#: right ones of whole and partial views mostly over 0.8.
MIN_FIT = 0.75
#: The closeness's distance, voxels. At one voxel a near-symmetric wrong pose fits within
#: 0.01 of the right one or better (a box turned half a turn); at a quarter voxel the three
#: wrong poses that were placed best were 0.044-0.058 less close than a right rival, and
#: right poses led wrong rivals by 0.008 or more (once trailed, by 0.012: no early stop).
CLOSE_DISTANCE = 0.25
#: Least lead in closeness of the best placed pose, polished, over the pose the search
#: returned for it to be returned instead (:func:`closer`): over the spread of the
#: closeness of one right pose polished two ways (95th percentile 0.03 on the view
#: suites). Occluded views 0-239: 6 poses won, none lost; full and partial views and the
#: dragon pairs, none either way.
CLOSER_MARGIN = 0.05
#: Placed hypotheses compared (the best and the distinct ones among the next).
CANDIDATES = 4
#: The short polish's correspondence distances, voxels: a wide pass to take the placed
#: pose (a few degrees off, on the Euler grid) into the basin, then one at the fit's.
ICP_DISTANCES = (2.0, 1.0)
#: The cell (voxels) the fixed cloud is thinned to for the confirmation (one point per
#: half voxel, as users tuned for speed run Open3D's tutorial polish): its short
#: point-to-plane ICP of one point per voxel reads the surface through the fixed cloud's
#: normals, not their spacing, and so does the closeness; a raw scan (25-30 points per
#: voxel) cost 6-7 times as much for the same planes (the confirm stage halved over the
#: bench's groups, the same successes or one more). The final polish keeps every point: on
#: the suites' views and crops of a scene, whose truth is exact, thinning either cloud
#: there cost 0.1-0.7 degree of median error.
FIXED_CELL = 0.5


@dataclass(frozen=True)
class Confirmation:
    """The outcome of :func:`confirm`.

    Attributes
    ----------
    transformation : ndarray, shape (4, 4)
        The best placed hypothesis after the short polish (moving cloud to fixed cloud).
    fit : float
        Its fit in [0, 1]: the share of its visible points within one voxel.
    runner_up : float
        The best fit of a distinct alternative (0 when none was placed).
    confirmed : bool
        ``fit >= MIN_FIT`` and no distinct alternative closer (:class:`Fit`).
    """

    transformation: NDArray[np.float64]
    fit: float
    runner_up: float
    confirmed: bool


class Fit(NamedTuple):
    """A pose polished and measured by :func:`fit`.

    Attributes
    ----------
    pose : ndarray, shape (4, 4)
        The polished pose (moving cloud to fixed cloud).
    share : float
        Its fit: the share of the visible points within one voxel of the fixed cloud.
    close : float
        Its closeness: the share within :data:`CLOSE_DISTANCE` voxels of the fixed
        surface's tangent plane at their nearest point.
    """

    pose: NDArray[np.float64]
    share: float
    close: float


def fit(
    stepper: SpectralStepper, moving: MovingCloud, fixed: o3d.geometry.PointCloud,
    pose: NDArray[np.float64], *, polish: bool = True,
) -> Fit:
    """Polish ``pose`` (4, 4) by the short ICP and measure its fit and closeness.

    Parameters
    ----------
    stepper : SpectralStepper
        For the visibility of the moving points (:meth:`SpectralStepper.visible`).
    moving : MovingCloud
        Its one-point-per-voxel points are polished.
    fixed : open3d.geometry.PointCloud
        The fixed cloud with normals, metres.
    pose : ndarray, shape (4, 4)
        Start of the polish.
    polish : bool
        False measures the fit at ``pose`` itself (a pose polished already).

    Returns
    -------
    Fit
        The polished pose, and the shares of the visible points within one voxel and
        within :data:`CLOSE_DISTANCE` voxels of ``fixed`` there.
    """
    voxel = stepper.voxel_size
    R, t = pose[:3, :3], pose[:3, 3]
    _, mask, _ = stepper.visible(moving, R, R @ moving.centroid + t - moving.centroid)
    points = moving.points if mask is None else moving.points[mask]
    near, kept = near_pose(fixed, points, pose, max(ICP_DISTANCES) * voxel)
    if len(kept) == 0:
        return Fit(pose, 0.0, 0.0)
    source = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    for distance in ICP_DISTANCES if polish else ():
        pose = point_to_plane_icp(source, near, distance * voxel, pose)
    measured = o3d.pipelines.registration.evaluate_registration(source, near, voxel, pose)
    pairs = np.asarray(measured.correspondence_set).reshape(-1, 2)  # nearest within a voxel
    posed = points[pairs[:, 0]] @ pose[:3, :3].T + pose[:3, 3]
    offsets = posed - np.asarray(near.points)[pairs[:, 1]]
    normals = np.asarray(near.normals)[pairs[:, 1]]
    along = np.einsum("ij,ij->i", offsets, normals) / np.maximum(lengths(normals), 1e-12)
    off_plane = np.abs(along)
    close = np.count_nonzero(off_plane < CLOSE_DISTANCE * voxel) / len(points)
    return Fit(pose, float(measured.fitness), float(close))


def confirm(
    stepper: SpectralStepper, moving: MovingCloud, fixed: o3d.geometry.PointCloud,
    ranked: list[Hypothesis], *, fits: dict | None = None, workers: int | None = 1,
) -> Confirmation:
    """Whether the best of ``ranked`` (placed hypotheses, best first) is clearly right.

    Parameters
    ----------
    stepper, moving
        As for :func:`fit`.
    fixed : open3d.geometry.PointCloud
        The fixed cloud with normals, metres.
    ranked : list of Hypothesis
        The search's placed hypotheses, best first (at least one).
    fits : dict, optional
        :func:`fit`'s results (:class:`Fit`) by hypothesis key
        (:attr:`~o3d_spectral.search.placement.Hypothesis.key`), kept across calls on the
        same clouds: a hypothesis still among the best after the sweep is not polished
        again. Hypotheses without a key are keyed by their rank.
    workers : int or None
        Threads (all cores when None). On one, the rivals are polished only where the
        best fits; on more, the :data:`CANDIDATES` are polished side by side at once
        (each the same whatever the thread: the outcome does not change).

    Returns
    -------
    Confirmation
    """
    fits = {} if fits is None else fits
    candidates = ranked[:CANDIDATES]
    keys = [hypothesis.key or ("rank", i) for i, hypothesis in enumerate(candidates)]
    starts = {key: h.transformation(moving.centroid) for key, h in zip(keys, candidates,
                                                                        strict=True)}
    if resolved_workers(workers) > 1:
        missing = [key for key in starts if key not in fits]
        polished = thread_map(lambda key: fit(stepper, moving, fixed, starts[key]), missing,
                              workers)
        fits.update(zip(missing, polished, strict=True))

    def fitted(key: tuple) -> Fit:
        if key not in fits:
            fits[key] = fit(stepper, moving, fixed, starts[key])
        return fits[key]

    best = fitted(keys[0])
    rivals = []
    if best.share >= MIN_FIT:
        rivals = [other for other in map(fitted, keys[1:]) if distinct(other.pose, best.pose)]
    confirmed = best.share >= MIN_FIT and all(other.close <= best.close for other in rivals)
    runner_up = max((other.share for other in rivals), default=0.0)
    return Confirmation(best.pose, best.share, runner_up, confirmed)


def closer(placed: Fit, returned: Fit) -> bool:
    """Whether the best placed pose, polished (``placed``, the confirmation's), lies
    clearly closer to the fixed cloud than the pose the search returned when nothing was
    confirmed (``returned``, measured where it is: ``fit(..., polish=False)``): more of
    its points within :data:`CLOSE_DISTANCE`, by over :data:`CLOSER_MARGIN`. The climbs
    rank poses by the spectral score, which a view half hidden can mislead (a pose that
    matches what hides the object); the closeness measures the pose against the points.
    """
    return placed.close > returned.close + CLOSER_MARGIN
