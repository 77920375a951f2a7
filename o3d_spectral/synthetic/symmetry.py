"""Geometric symmetries of the bundled objects: their groups, found on the meshes.

A symmetry of a model is a rigid motion ``S`` (4x4) with ``S(model) == model`` up to a small
surface residual. Each model's kinds of symmetry are recorded in a table; their axes start
at the principal axes of the mesh surface (:func:`surface_moments`) and are refined on the
mesh (:func:`refine_axis`). The pose errors that minimise over a group are in
:mod:`o3d_spectral.harness.errors`.

All transforms are 4x4 float64 arrays; distances are in metres.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cache

import numpy as np
import open3d as o3d

from o3d_spectral.refinement.icp import point_to_plane_icp
from o3d_spectral.spectra import so3
from o3d_spectral.synthetic.constants import REFINE_DISTANCE
from o3d_spectral.synthetic.models import load_model

__all__ = [
    "SYMMETRIC_MODELS",
    "Symmetry",
    "closure",
    "model_symmetry",
    "refine_axis",
    "surface_moments",
    "surface_symmetry",
]


#: Rotation (degrees) about a continuous axis whose self-alignment refines that axis.
_CONTINUOUS_PROBE = 90.0

# Symmetries per model, in the model's principal frame (eigenvectors of the surface's second
# moments, ascending eigenvalues: axis 0 is the "thinnest" direction). ``continuous`` is the
# principal axis of a continuous rotational symmetry; ``generators`` are (axis, angle in
# degrees) rotations that generate the discrete part. Each axis is then refined on the mesh
# (``model_symmetry``). Chosen from the surface residuals measured in docs/suites.md (kept
# when the mean residual about the refined axes is below 2 mm, i.e. below the sensor's axial
# noise at 1 m); models not listed have no symmetry.
_TABLE: dict[str, dict] = {
    "bowl": {"continuous": 0, "generators": ()},
    "master_chef_can": {"continuous": 2, "generators": ((0, 180.0),)},
    "tomato_soup_can": {"continuous": 2, "generators": ((0, 180.0),)},
    "cracker_box": {"continuous": None, "generators": ((0, 180.0), (1, 180.0))},
    "gelatin_box": {"continuous": None, "generators": ((0, 180.0), (1, 180.0))},
    "foam_brick": {"continuous": None, "generators": ((2, 90.0), (0, 180.0))},
    "potted_meat_can": {"continuous": None, "generators": ((1, 180.0),)},
    "mustard_bottle": {"continuous": None, "generators": ((2, 180.0),)},
    "scissors": {"continuous": None, "generators": ((2, 180.0),)},
}

#: Names of the bundled models that have a recorded symmetry.
SYMMETRIC_MODELS: tuple[str, ...] = tuple(sorted(_TABLE))


@dataclass(frozen=True)
class Symmetry:
    """Symmetry group ``{C(theta) @ D_k}`` of a model in some frame.

    Attributes
    ----------
    discrete : ndarray, shape (K, 4, 4), float64
        The discrete elements ``D_k``, the identity first. ``K == 1`` if there are none.
    axis : ndarray, shape (3,), or None
        Unit direction of the continuous rotation axis ``C(theta)``; None if there is none.
    center : ndarray, shape (3,)
        A point on the axis (m); the discrete elements fix it too.
    """

    discrete: np.ndarray = field(default_factory=lambda: np.eye(4)[None])
    axis: np.ndarray | None = None
    center: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __repr__(self) -> str:
        axis = None if self.axis is None else np.round(self.axis, 4).tolist()
        return f"Symmetry(discrete={len(self.discrete)}, axis={axis})"

    @property
    def is_trivial(self) -> bool:
        """True if the group holds only the identity."""
        return self.axis is None and len(self.discrete) == 1

    def transformed(self, frame_from_model: np.ndarray) -> Symmetry:
        """The same group expressed in another frame: ``S' = F @ S @ F^-1``.

        Use it to move a model's symmetry into the frame of a source cloud built as
        ``source = F @ model``.
        """
        f = np.asarray(frame_from_model, dtype=float)
        f_inv = np.linalg.inv(f)
        return Symmetry(
            discrete=f @ self.discrete @ f_inv,
            axis=None if self.axis is None else f[:3, :3] @ self.axis,
            center=f[:3, :3] @ self.center + f[:3, 3],
        )

    def elements(self, *, step: float = np.deg2rad(1.0)) -> np.ndarray:
        """All group elements, the continuous part sampled every ``step`` radians.

        Returns
        -------
        ndarray, shape (M, 4, 4), float64
            ``M = K`` without a continuous axis, else ``K * ceil(2 pi / step)``.
        """
        if self.axis is None:
            return self.discrete.copy()
        if step <= 0:
            raise ValueError(f"step must be > 0 radians, got {step}")
        angles = np.linspace(0.0, 2 * np.pi, int(np.ceil(2 * np.pi / step)), endpoint=False)
        rotations = np.stack([_about_point(self.axis, a, self.center) for a in angles])
        return (rotations[:, None] @ self.discrete[None]).reshape(-1, 4, 4)


def _about_point(axis: np.ndarray, angle: float, center: np.ndarray) -> np.ndarray:
    """4x4 rotation by ``angle`` about the line through ``center`` along ``axis``."""
    return so3.about_pivot(so3.exp(np.asarray(axis) * angle), np.zeros(3), center)


def closure(generators: list[np.ndarray]) -> np.ndarray:
    """The finite group generated by 4x4 ``generators`` (identity first), shape (K, 4, 4):
    the ``discrete`` part of a :class:`Symmetry`."""
    group = [np.eye(4)]
    frontier = list(group)
    while frontier:
        new = []
        for g in frontier:
            for h in generators:
                candidate = h @ g
                if not any(np.allclose(candidate, e, atol=1e-9) for e in group + new):
                    new.append(candidate)
        group += new
        frontier = new
    return np.stack(group)


def surface_moments(mesh: o3d.geometry.TriangleMesh) -> tuple[np.ndarray, np.ndarray]:
    """Area-weighted centroid and principal axes of a mesh surface (exact, no sampling).

    Returns
    -------
    center : ndarray, shape (3,)
        Surface centroid (m).
    axes : ndarray, shape (3, 3)
        Columns are the principal directions, by ascending second moment.
    """
    v = np.asarray(mesh.vertices)
    t = np.asarray(mesh.triangles)
    a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    s = a + b + c
    center = area @ s / (3 * area.sum())
    # Exact second moment of a triangle: A/12 (a a^T + b b^T + c c^T + s s^T).
    second = np.einsum("n,ni,nj->ij", area, a, a) + np.einsum("n,ni,nj->ij", area, b, b)
    second += np.einsum("n,ni,nj->ij", area, c, c) + np.einsum("n,ni,nj->ij", area, s, s)
    covariance = second / (12 * area.sum()) - np.outer(center, center)
    return center, np.linalg.eigh(covariance)[1]


def _vertex_cloud(mesh: o3d.geometry.TriangleMesh) -> o3d.geometry.PointCloud:
    """The mesh's vertices with their normals, as a point cloud."""
    cloud = o3d.geometry.PointCloud(mesh.vertices)
    cloud.normals = mesh.vertex_normals
    return cloud


def refine_axis(
    cloud: o3d.geometry.PointCloud, axis: np.ndarray, angle: float, center: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The symmetry axis near ``axis`` that maps a surface best onto itself.

    The rotation by ``angle`` (radians) about the line through ``center`` along unit
    ``axis`` is refined by point-to-plane ICP of the surface onto itself; the refined
    motion's rotation axis and its fixed line are returned.

    Parameters
    ----------
    cloud : open3d.geometry.PointCloud
        Surface points with normals (m).
    axis : ndarray, shape (3,)
        Initial unit direction.
    angle : float
        Radians; for a continuous axis any angle that is not a multiple of 2 pi.
    center : ndarray, shape (3,)
        Initial point on the axis (m).

    Returns
    -------
    axis : ndarray, shape (3,)
        Refined unit direction, on the side of the given one.
    point : ndarray, shape (3,)
        The point of the refined axis nearest ``center`` (m).
    """
    refined = point_to_plane_icp(cloud, cloud, REFINE_DISTANCE, _about_point(axis, angle, center))
    direction = so3.log(refined[:3, :3])
    direction /= np.linalg.norm(direction)
    direction *= np.sign(direction @ axis)
    # Points of the axis are fixed: (I - R) p = t; least squares picks one of them.
    point = np.linalg.lstsq(np.eye(3) - refined[:3, :3], refined[:3, 3], rcond=None)[0]
    point += ((center - point) @ direction) * direction
    return direction, point


def _nearest_point(directions: list[np.ndarray], points: list[np.ndarray]) -> np.ndarray:
    """Least-squares point nearest to the lines ``points[k] + s directions[k]`` (two or
    more, not all parallel)."""
    projectors = [np.eye(3) - np.outer(d, d) for d in directions]
    moments = sum(p @ x for p, x in zip(projectors, points, strict=True))
    return np.linalg.solve(sum(projectors), moments)


@cache
def model_symmetry(name: str) -> Symmetry:
    """Symmetry group of the bundled model ``name``, in the mesh's own frame.

    The kinds of symmetry per model are listed in ``docs/suites.md``; models without a
    symmetry get the trivial group. See :func:`surface_symmetry` for how the axes are
    found.
    """
    spec = _TABLE.get(name)
    if spec is None:
        load_model(name)  # raises ValueError for unknown names
        return Symmetry()
    mesh = load_model(name)
    center, principal = surface_moments(mesh)
    return surface_symmetry(_vertex_cloud(mesh), name, center, principal)


def surface_symmetry(
    cloud: o3d.geometry.PointCloud, name: str, center: np.ndarray, principal: np.ndarray
) -> Symmetry:
    """The symmetry group recorded for the object ``name``, found on a surface of it.

    Each axis starts as a principal axis of the surface (``principal``: columns by
    ascending second moment, about ``center``) and is refined by :func:`refine_axis`: the
    principal axes of a real scan are a few degrees off its symmetry axes wherever a
    detail (a lid, a pull tab) is not symmetric, and are arbitrary in a square section.
    The refined axes are made orthogonal in the order continuous first, then generators;
    their common point is the least-squares nearest point to the refined axes.

    Parameters
    ----------
    cloud : open3d.geometry.PointCloud
        Points of the object's surface with normals (m), in the frame wanted.
    name : str
        A bundled model's name (the trivial group for names without a symmetry).
    center : ndarray, shape (3,)
    principal : ndarray, shape (3, 3)
    """
    spec = _TABLE.get(name)
    if spec is None:
        return Symmetry()
    probes = {i: np.deg2rad(angle) for i, angle in spec["generators"]}
    if spec["continuous"] is not None:
        probes = {spec["continuous"]: np.deg2rad(_CONTINUOUS_PROBE), **probes}
    directions, points = [], []
    for i, angle in probes.items():
        direction, point = refine_axis(cloud, principal[:, i], angle, center)
        for previous in directions:  # Gram-Schmidt, in the order of ``probes``
            direction = direction - (direction @ previous) * previous
        directions.append(direction / np.linalg.norm(direction))
        points.append(point)
    if len(directions) > 1:
        center = _nearest_point(directions, points)
    else:
        center = points[0]
    axes = dict(zip(probes, directions, strict=True))
    generators = [
        _about_point(axes[i], np.deg2rad(angle), center) for i, angle in spec["generators"]
    ]
    continuous = spec["continuous"]
    return Symmetry(
        discrete=closure(generators),
        axis=None if continuous is None else axes[continuous].copy(),
        center=center,
    )
