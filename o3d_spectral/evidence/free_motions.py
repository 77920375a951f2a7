"""The motions a pose's overlap leaves free: where the source could move with its fit
unchanged.

A pose is held by its *inliers* (the source points within a voxel of the target) where
their point-to-plane constraints hold it (Gelfand, Ikemoto, Rusinkiewicz and Levoy,
*Geometrically stable sampling for the ICP algorithm*, 3DIM 2003): a point ``p`` with
unit normal ``n`` resists the small motion of rotation ``w`` about a centre ``c`` and
translation ``u`` by ``((p - c) x n) . w + n . u``. Summed over the inliers, the squares
make a 6 x 6 matrix; a motion along an eigenvector whose eigenvalue is under
:data:`SUPPORT_FLOOR` times the mean of the six moves the inliers along their own surface:
a turn about a cylinder's axis, a slide along a plane or a cylinder.

Such a motion is *free* where it goes on: :func:`free_motions` moves the inliers along it
in even steps either way until fewer than :data:`STAYING` of them lie over the target's
surface, or those that do lie :data:`PLANE_SLACK` voxels farther across it (a point that
leaves the target's surface along it moves where the target shows nothing: that neither
holds the motion nor contradicts it), and keeps it where it went farther than a pose's tolerance
(:data:`TURN_TOLERANCE` degrees, :data:`SLIDE_TOLERANCE` voxels) both ways together. Two
views of a box sharing one face leave that face's two slides and its turn free; two views
of a can sharing a band of its side leave the turn about its axis free.

Whether the motion is also a *symmetry* of the source decides what it means: where the
whole source (not only the overlap) resists it no more than the floor, the source maps
onto itself along it (a can turned about its axis), and the pose is right up to that
symmetry; otherwise (a box slid along one face, a mug turned with its handle shown by one
view only) the data do not fix the pose along it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from ..io.cloud import MIN_POINTS
from ..io.rows import known, lengths
from ..spectra import so3
from .constants import (
    MAX_STEPS,
    PLANE_SLACK,
    SLIDE_REACH,
    SLIDE_ROTATION,
    SLIDE_TOLERANCE,
    STAYING,
    SUPPORT_FLOOR,
    TURN_TOLERANCE,
)

__all__ = ["FreeMotion", "Overlap", "free_motions", "unresisted_motions", "constraint_rows",
           "leaves_motion_free", "support_floor", "turn_axis_point", "SUPPORT_FLOOR", "PLANE_SLACK",
           "STAYING", "TURN_TOLERANCE", "SLIDE_TOLERANCE", "SLIDE_ROTATION", "SLIDE_REACH",
           "MAX_STEPS"]


@dataclass(frozen=True)
class FreeMotion:
    """A motion of the source that leaves its fit to the target unchanged.

    Attributes
    ----------
    kind : {"turn", "slide"}
        A turn about an axis, or a slide along a direction.
    axis : ndarray, shape (3,)
        Unit direction of the turn's axis, or of the slide.
    point : ndarray, shape (3,)
        A point on the turn's axis; for a slide, the inliers' centroid (metres).
    reach : tuple of float
        How far the motion goes each way with the fit unchanged, from the pose,
        ``(low, high)`` with ``low <= 0 <= high``: degrees about ``axis`` (right-handed)
        for a turn, metres along ``axis`` for a slide; a whole turn is (-180, 180).
    symmetric : bool
        The whole source resists the motion no more than its overlap: a symmetry of the
        source (the pose is right up to it; where the source is a single view, only if
        the object shares it) rather than a motion the data do not fix.
    """

    kind: str
    axis: NDArray[np.float64]
    point: NDArray[np.float64]
    reach: tuple[float, float]
    symmetric: bool

    @property
    def extent(self) -> float:
        """``high - low`` of :attr:`reach`: degrees (turn) or metres (slide)."""
        return self.reach[1] - self.reach[0]

    def transformation(self, amount: float) -> NDArray[np.float64]:
        """The motion by ``amount`` (degrees for a turn, metres for a slide), (4, 4)."""
        return _moved_by(self.kind, self.axis, self.point, amount)

    def shifted(self, offset: NDArray[np.float64]) -> FreeMotion:
        """The same motion with the frame's origin moved by ``-offset`` (3,): its point
        plus ``offset``."""
        return FreeMotion(self.kind, self.axis, self.point + offset, self.reach, self.symmetric)

    def describe(self) -> str:
        """One line: how far it goes, along what (the direction only: the same in any
        frame that differs by a shift)."""
        a = ", ".join(f"{x:.2f}" for x in self.axis)
        low, high = self.reach
        if self.kind == "turn":
            return f"turned about an axis along ({a}) by {low:.0f} to {high:.0f} deg"
        return f"slid along ({a}) by {low:.3g} to {high:.3g} m"


def constraint_rows(
    points: NDArray[np.float64], normals: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """Each point's resistance to the six small motions about the points' centroid.

    Parameters
    ----------
    points, normals : ndarray, shape (M, 3)
        Points (metres) and their unit normals (either sign), M >= 1.

    Returns
    -------
    rows : ndarray, shape (M, 6)
        ``((p - c) / L x n, n)``: the residual of the motion (``w L``, ``u``) is the row
        times it (``L`` makes the rotation a length).
    centre : ndarray, shape (3,)
        The centroid ``c`` (metres).
    scale : float
        ``L``, the points' RMS distance to ``c`` (metres).
    """
    centre = points.mean(axis=0)
    scale = max(float(np.sqrt(np.mean(np.sum((points - centre) ** 2, axis=1)))), 1e-12)
    return np.hstack([np.cross((points - centre) / scale, normals), normals]), centre, scale


def support_floor(matrix: NDArray[np.float64]) -> float:
    """:data:`SUPPORT_FLOOR` times the mean constraint over the six motions of a
    constraint ``matrix`` (6, 6; the rows' ``rows.T @ rows``, :func:`constraint_rows`):
    a motion constrained less is not resisted."""
    return SUPPORT_FLOOR * float(np.trace(matrix)) / 6.0


def turn_axis_point(rotation: NDArray[np.float64], translation: NDArray[np.float64],
                    centre: NDArray[np.float64]) -> NDArray[np.float64]:
    """A point on the axis of the small motion ``p -> p + rotation x (p - centre) +
    translation`` (``rotation`` non-zero, radians; metres): ``centre + rotation x
    translation / |rotation|^2``, the foot of the axis nearest ``centre``."""
    return centre + np.cross(rotation, translation) / float(np.linalg.norm(rotation)) ** 2


def leaves_motion_free(points: NDArray[np.float64], normals: NDArray[np.float64]) -> bool:
    """Whether a surface leaves some rigid motion free: the least constraint its points
    put on a motion is under :data:`SUPPORT_FLOOR` times the mean over the six motions
    (see :data:`SUPPORT_FLOOR` for what the bundled models' views give).

    Parameters
    ----------
    points, normals : ndarray, shape (M, 3)
        Points (metres) and their unit normals (either sign), M >= 1.
    """
    rows, _, _ = constraint_rows(points, normals)
    every = rows.T @ rows
    return bool(np.linalg.eigvalsh(every)[0] < support_floor(every))


def unresisted_motions(
    points: NDArray[np.float64], normals: NDArray[np.float64]
) -> list[tuple[str, NDArray[np.float64], NDArray[np.float64]]]:
    """The motions the points barely resist, as turns about axes and slides.

    The eigenvectors of the constraint (:func:`constraint_rows`) under
    :data:`SUPPORT_FLOOR` of its mean span the unresisted motions; within that span, the
    motions without rotation (their rotations' null space, :data:`SLIDE_ROTATION`) are
    slides, and each remaining direction is a turn: a rotation ``w`` with translation
    ``u`` of the centre ``c`` (the slides' part taken out) turns about the line along
    ``w`` through ``c + w x u / |w|^2``.

    Parameters
    ----------
    points, normals : ndarray, shape (M, 3)
        Points (metres) and unit normals, M >= 1.

    Returns
    -------
    list of (kind, axis, point)
        ``"turn"`` with its unit axis (3,) and a point on it (3,, metres), or
        ``"slide"`` with its unit direction (3,) and the points' centroid; slides first.
    """
    rows, centre, scale = constraint_rows(points, normals)
    matrix = rows.T @ rows
    values, vectors = np.linalg.eigh(matrix)
    span = vectors[:, values < support_floor(matrix)]  # (6, k)
    if span.shape[1] == 0:
        return []
    _, strength, directions = np.linalg.svd(span[:3], full_matrices=True)  # rotation parts
    strength = np.r_[strength, np.zeros(span.shape[1] - len(strength))]
    turning = strength >= SLIDE_ROTATION
    slides = span[3:] @ directions[~turning].T  # (3, s): their translations
    basis = np.linalg.svd(slides, full_matrices=False)[0] if slides.size else np.zeros((3, 0))
    found: list[tuple[str, NDArray[np.float64], NDArray[np.float64]]] = [
        ("slide", direction, centre.copy()) for direction in basis.T]
    for motion in (span @ directions[turning].T).T:
        w, u = motion[:3] / scale, motion[3:]
        u = u - basis @ (basis.T @ u)  # a slide added to a turn is still free
        found.append(("turn", w / float(np.linalg.norm(w)), turn_axis_point(w, u, centre)))
    return found


def free_motions(
    points: NDArray[np.float64], normals: NDArray[np.float64], inlier: NDArray[np.bool_],
    target_points: NDArray[np.float64], target_normals: NDArray[np.float64], tree: cKDTree,
    voxel_size: float, whole_points: NDArray[np.float64], whole_normals: NDArray[np.float64],
) -> tuple[FreeMotion, ...]:
    """The free motions of a posed source (see the module docstring).

    Parameters
    ----------
    points, normals : ndarray, shape (M, 3)
        The posed source points the target could show (metres) and their unit normals
        (zero rows where unknown).
    inlier : ndarray of bool, shape (M,)
        Those within a voxel of the target.
    target_points, target_normals : ndarray, shape (N, 3)
        The target points ``tree`` holds (metres) and their unit normals.
    tree : scipy.spatial.cKDTree
        A KD-tree of ``target_points``.
    voxel_size : float
        Metres: steps and distances are measured in it.
    whole_points, whole_normals : ndarray, shape (K, 3)
        The whole posed source and its normals (zero rows where unknown): a free motion
        it resists is no symmetry of the source, and the data leave the pose unfixed
        along it.

    Returns
    -------
    tuple of FreeMotion
        Empty where none is free or fewer than :data:`~o3d_spectral.io.cloud.MIN_POINTS`
        inliers have normals.
    """
    keep = inlier & known(normals)
    if keep.sum() < MIN_POINTS:
        return ()
    held, held_normals = points[keep], normals[keep]
    v = float(voxel_size)
    overlap = Overlap(held, tree, target_points, target_normals, v)
    limit = overlap.at(np.eye(4))[1] + PLANE_SLACK
    whole = known(whole_normals)
    found = []
    for kind, axis, point in unresisted_motions(held, held_normals):
        reach = _reach(overlap, limit, kind, axis, point, v)
        if reach[1] - reach[0] > (TURN_TOLERANCE if kind == "turn" else SLIDE_TOLERANCE * v):
            symmetric = not _resists(whole_points[whole], whole_normals[whole], kind, axis,
                                     point)
            found.append(FreeMotion(kind, axis, point, reach, symmetric))
    return tuple(found)


class Overlap:
    """How points moved by a rigid motion lie on a target: how many stay over its surface
    (their nearest target point within a voxel along the surface) and how far those are
    across it.

    Parameters
    ----------
    points : ndarray, shape (M, 3)
        The points (metres).
    tree : scipy.spatial.cKDTree
        A KD-tree of ``target_points``.
    target_points, target_normals : ndarray, shape (N, 3)
        Metres, unit normals.
    voxel_size : float
        Metres.
    """

    def __init__(self, points: NDArray[np.float64], tree: cKDTree,
                 target_points: NDArray[np.float64], target_normals: NDArray[np.float64],
                 voxel_size: float) -> None:
        self.points, self.tree, self.voxel_size = points, tree, voxel_size
        self.target_points, self.target_normals = target_points, target_normals

    def at(self, motion: NDArray[np.float64]) -> tuple[float, float]:
        """After ``motion`` (4, 4): the share of the points over the target's surface,
        and their median distance to its tangent planes (voxels; inf where none is)."""
        moved = self.points @ motion[:3, :3].T + motion[:3, 3]
        _, nearest = self.tree.query(moved)
        offsets = moved - self.target_points[nearest]
        normals = self.target_normals[nearest]
        across = np.einsum("ij,ij->i", offsets, normals)
        along = lengths(offsets - across[:, None] * normals)
        over = along <= self.voxel_size
        if not over.any():
            return 0.0, float("inf")
        return float(np.mean(over)), float(np.median(np.abs(across[over]))) / self.voxel_size


def _moved_by(kind: str, axis: NDArray[np.float64], point: NDArray[np.float64],
              amount: float) -> NDArray[np.float64]:
    """A turn by ``amount`` degrees about the line along ``axis`` through ``point``, or a
    slide by ``amount`` metres along ``axis`` (4, 4)."""
    if kind == "turn":
        return so3.about_pivot(so3.exp(np.deg2rad(amount) * axis), np.zeros(3), point)
    motion = np.eye(4)
    motion[:3, 3] = amount * axis
    return motion


def _reach(overlap: Overlap, limit: float, kind: str, axis: NDArray[np.float64],
           point: NDArray[np.float64], voxel_size: float) -> tuple[float, float]:
    """How far the motion goes each way while :data:`STAYING` of the points stay over the
    target's surface, their median distance across it within ``limit`` voxels: (low <= 0,
    high >= 0), the last step that did, degrees or metres."""
    held = overlap.points
    if kind == "turn":
        offsets = held - point
        radius = float(np.max(lengths(offsets - np.outer(offsets @ axis, axis))))
        end, finest = 180.0, np.rad2deg(voxel_size / max(radius, 1e-12))
    else:
        end = float(np.max(lengths(held - held.mean(axis=0)))) * SLIDE_REACH
        finest = voxel_size
    steps = min(MAX_STEPS, max(1, int(np.ceil(end / finest))))
    reach = []
    for sign in (-1.0, 1.0):
        last = 0.0
        for k in range(1, steps + 1):
            amount = end * k / steps
            staying, across = overlap.at(_moved_by(kind, axis, point, sign * amount))
            if staying < STAYING or across > limit:
                break
            last = amount
        reach.append(sign * last)
    return reach[0], reach[1]


def _resists(points: NDArray[np.float64], normals: NDArray[np.float64], kind: str,
             axis: NDArray[np.float64], point: NDArray[np.float64]) -> bool:
    """Whether ``points`` with ``normals`` resist the motion over :data:`SUPPORT_FLOOR`
    of their mean constraint (:func:`constraint_rows`)."""
    if len(points) < MIN_POINTS:
        return False
    rows, centre, scale = constraint_rows(points, normals)
    if kind == "turn":  # w x (p - point) = w x (p - centre) + w x (centre - point)
        motion = np.r_[axis * scale, np.cross(axis, centre - point)]
    else:
        motion = np.r_[np.zeros(3), axis]
    motion /= np.linalg.norm(motion)
    matrix = rows.T @ rows
    return bool(motion @ matrix @ motion >= support_floor(matrix))
