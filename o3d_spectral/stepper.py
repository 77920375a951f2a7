"""The control law (paper, eq. control_law and Algorithm 1) as a reusable stepper.

A :class:`SpectralStepper` holds the fixed cloud's spectra, computed once: its voxel
grid's 3D FFT and its EGI's spherical-harmonic coefficients. For a moving cloud at a pose
``x -> R (x - c) + c + T`` (``c``: the moving cloud's centroid, the paper's rotation about
the centre of gravity) :meth:`SpectralStepper.evaluate` returns the full corrections:

- translation ``grad_glob T`` (metres): the phase-correlation shift that takes the moved
  cloud onto the fixed one (eq. fourier_shift_solution), sub-voxel;
- rotation (radians): ``grad C_r`` (eq. cr_derivative) divided by the correlation's
  curvature (:func:`o3d_spectral.rotation.rotation_step`),

and the law applies ``T <- T + lambda_t grad_glob T``, ``R <- R exp(lambda_r hat(step))``.
:meth:`SpectralStepper.step` does one cycle for a freshly captured cloud (pose identity),
as visual servoing needs; :func:`o3d_spectral.registration_spectral` iterates
:meth:`~SpectralStepper.evaluate` on one source cloud. Both can start from
:meth:`SpectralStepper.hypotheses`: the peaks of the rotation correlation over the whole
of SO(3), each placed by phase correlation.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from . import so3
from .cloud import MIN_POINTS, PreparedCloud, as_arrays, prepare
from .egi import coefficients as egi_coefficients
from .egi import facing, normalise, smooth
from .fft import RealFFT3, fft_plan, next_fast_len
from .grid import Box, Lattice, check_memory, splat
from .options import SpectralRegistrationOption
from .rotation import RotationGradient, curvature_scale, gradient, rotation_step
from .so3fft import CorrelationGrid, correlation_grid, peaks, visible_correlation_grid
from .translation import cross_power_peak

__all__ = ["MovingCloud", "Evaluation", "Hypothesis", "Step", "SpectralStepper", "FOCUS_SHARE"]

#: :meth:`SpectralStepper.focused` keeps the whole EGI when the points it is given keep
#: over this share of the fixed cloud's normals.
FOCUS_SHARE = 0.9


@dataclass(frozen=True)
class MovingCloud:
    """A moving cloud ready for :meth:`SpectralStepper.evaluate`.

    Attributes
    ----------
    points : ndarray, shape (M, 3)
        Down-sampled points (metres), one per voxel.
    point_normals : ndarray, shape (M, 3)
        Their mean normals (unit, or zero), for the visibility test.
    centroid : ndarray, shape (3,)
        Pivot of the rotation, metres.
    radius : float
        Largest distance of a point from the centroid, metres.
    coefficients : ndarray, shape (B, 2B - 1)
        EGI coefficients ``F^l`` before smoothing and normalisation.
    """

    points: NDArray[np.float64]
    point_normals: NDArray[np.float64]
    centroid: NDArray[np.float64]
    radius: float
    coefficients: NDArray[np.float64]

    def posed(self, rotation: NDArray[np.float64], translation: ArrayLike) -> NDArray[np.float64]:
        """The points at the pose ``x -> R (x - c) + c + T``, shape (M, 3)."""
        return (self.points - self.centroid) @ rotation.T + self.centroid + translation


@dataclass(frozen=True)
class Evaluation:
    """Full corrections and costs at one pose of the moving cloud.

    Attributes
    ----------
    translation : ndarray, shape (3,)
        ``grad_glob T``: shift (metres, fixed frame) taking the moved cloud onto the fixed one.
    rotation : ndarray, shape (3,)
        Rotation step (radians) for a right perturbation ``R exp(hat(rotation))``.
    rotation_gradient : ndarray, shape (3,)
        The paper's ``grad C_r(R, e_k)``, before scaling.
    correlation : float
        ``C_r(R)`` of the normalised EGIs, in [-1/4pi, 1/4pi].
    translation_peak : float
        Height of the phase-correlation peak in [0, 1] (1: identical grids).
    cost_translation, cost_rotation : float
        ``J_t`` and ``J_r`` (eqs. translation_cost_function, rotation_cost_function) on
        unit-norm grids and coefficients, each in [0, 2].
    """

    translation: NDArray[np.float64]
    rotation: NDArray[np.float64]
    rotation_gradient: NDArray[np.float64]
    correlation: float
    translation_peak: float
    cost_translation: float
    cost_rotation: float


def _evaluation(
    translation: NDArray[np.float64],
    rotation: NDArray[np.float64],
    local: RotationGradient,
    peak: float,
    cost_translation: float,
) -> Evaluation:
    """An :class:`Evaluation` from the full corrections, the rotation correlation's
    derivatives ``local`` at the pose, the phase-correlation peak and ``J_t``."""
    return Evaluation(
        translation=translation,
        rotation=rotation,
        rotation_gradient=local.gradient,
        correlation=local.value,
        translation_peak=peak,
        cost_translation=cost_translation,
        cost_rotation=float(1.0 - 4.0 * np.pi * local.value),
    )


@dataclass(frozen=True)
class Hypothesis:
    """A peak of the rotation correlation over SO(3), placed by phase correlation.

    The moving cloud fits the fixed one at ``x -> rotation (x - c) + centre`` (``c``:
    its centroid).

    Attributes
    ----------
    rotation : ndarray, shape (3, 3)
        The peak's rotation, about the moving cloud's centroid.
    centre : ndarray, shape (3,)
        Where the phase correlation puts the turned cloud's centroid, metres.
    translation_peak : float
        Height of that phase-correlation peak in [0, 1].
    cost_translation : float
        ``J_t`` of the turned cloud before that shift, in [0, 2].
    score : float
        ``translation_peak``, or the fitness there (``option.hypothesis_score``).
    """

    rotation: NDArray[np.float64]
    centre: NDArray[np.float64]
    translation_peak: float
    cost_translation: float
    score: float


@dataclass(frozen=True)
class Step:
    """Increments of one control cycle for a captured cloud.

    The moving cloud should be moved by ``x -> delta_rotation (x - pivot) + pivot +
    delta_translation`` (equivalently by :attr:`transformation`); a camera that observes
    it moves by the inverse.

    Attributes
    ----------
    delta_rotation : ndarray, shape (3, 3)
        ``exp(lambda_r hat(rotation step))``.
    delta_translation : ndarray, shape (3,)
        ``lambda_t grad_glob T``, metres.
    pivot : ndarray, shape (3,)
        Centroid of the captured cloud, metres.
    evaluation : Evaluation
        Full corrections and costs.
    """

    delta_rotation: NDArray[np.float64]
    delta_translation: NDArray[np.float64]
    pivot: NDArray[np.float64]
    evaluation: Evaluation

    @property
    def transformation(self) -> NDArray[np.float64]:
        """The increment as a 4x4 rigid transform in the cloud's frame."""
        out = np.eye(4)
        out[:3, :3] = self.delta_rotation
        out[:3, 3] = self.pivot + self.delta_translation - self.delta_rotation @ self.pivot
        return out


class SpectralStepper:
    """Spectra of a fixed cloud, and the control law against it.

    Parameters
    ----------
    target : PointCloud, tensor PointCloud or ndarray (N, 3) / (N, 6)
        The fixed cloud (reference), metres. Not modified. Normals are estimated when
        absent (see :func:`o3d_spectral.cloud.prepare`).
    voxel_size : float
        Voxel edge ``r``, metres (the paper: 0.008).
    option : SpectralRegistrationOption, optional

    Notes
    -----
    Grids of the moving cloud are cubes large enough to hold it under any rotation; the
    FFT size per axis is the fixed grid's size plus the moving grid's (rounded up to a
    fast length), which keeps every shift between the two unambiguous whatever the
    distance between the clouds.
    """

    def __init__(
        self,
        target: object,
        voxel_size: float,
        *,
        option: SpectralRegistrationOption | None = None,
    ) -> None:
        if not (np.isfinite(voxel_size) and voxel_size > 0):
            raise ValueError(f"voxel_size must be a positive number of metres, got {voxel_size}")
        self.option = option or SpectralRegistrationOption()
        self.voxel_size = float(voxel_size)
        prepared = self._prepare(target, "target")
        points = prepared.points
        self._set_grid(points, self.voxel_size)
        self._target_normals, self._target_normal_points = prepared.normals, prepared.normal_points
        self._normals_centre = prepared.normal_points.mean(axis=0)
        raw = self._egi(prepared.normals)
        self.target_coefficients = self._smoothed_levels(raw)
        self.target_points = points
        self.viewpoint = self._viewpoint(prepared)
        self.reset()

    def _set_grid(self, points: NDArray[np.float64], voxel_size: float) -> None:
        """The fixed voxel grid: ``points`` (metres) splatted on voxels of ``voxel_size``."""
        self.voxel_size = voxel_size
        lower, upper = points.min(axis=0), points.max(axis=0)
        self.lattice = Lattice(np.floor(lower / voxel_size) * voxel_size, voxel_size)
        self.target_box = self.lattice.box_around(lower, upper, margin=2)
        check_memory(self.target_box.shape, self.option.max_grid_memory, "target")
        grid = splat(points, self.target_box, mode=self.option.voxel_weighting)
        self._target_grid = grid / np.linalg.norm(grid)
        self._target_spectra: dict[tuple, NDArray[np.complexfloating]] = {}

    def coarsened(self, factor: int) -> SpectralStepper:
        """This stepper with voxels ``factor`` times larger, for placing many rotations
        cheaply (a grid ``factor**3`` times smaller).

        The fixed grid is the same down-sampled points splatted on the coarser lattice;
        the EGI spectra are shared. Moving clouds from :meth:`moving` work with both.
        """
        out = copy.copy(self)
        out._set_grid(self.target_points, self.voxel_size * factor)
        return out

    def _viewpoint(self, target: PreparedCloud) -> NDArray[np.float64] | None:
        """Sensor position of a single-view target, or None (see ``target_viewpoint``)."""
        choice = self.option.target_viewpoint
        if choice is None:
            return None
        if not isinstance(choice, str):
            return np.asarray(choice, dtype=np.float64)
        sensor = np.zeros(3)
        has_normal = np.any(target.point_normals != 0.0, axis=1)
        facing = np.einsum("ij,ij->i", target.point_normals, sensor - target.points) > 0.0
        return sensor if facing[has_normal].mean() >= 0.9 else None

    @cached_property
    def _target_tree(self) -> cKDTree:
        """KD-tree of the fixed cloud's voxels, built on first use (hypothesis ranking)."""
        return cKDTree(self.target_points)

    def focused(self, near: ArrayLike, radius: float) -> SpectralStepper:
        """This stepper with the fixed EGI made only of the fixed cloud's normals within
        ``radius`` (metres) of one of the points ``near`` (metres, shape (K, 3)).

        In a scene much larger than the moving cloud (a tabletop against one object's
        model) the whole scene's EGI is dominated by the table and the other objects;
        once the phase correlation has located the moving cloud, the normals around it
        (a ball about its centroid, or the moving cloud's own points at an estimated
        pose) are the ones its EGI should match. The voxel grid, its spectra and the
        translation search are shared with this stepper, unchanged. Returns ``self``
        when over ``FOCUS_SHARE`` of the normals are kept (nothing to gain) or fewer
        than ``MIN_POINTS``.
        """
        tree = cKDTree(np.asarray(near, dtype=np.float64).reshape(-1, 3))
        distances, _ = tree.query(self._target_normal_points, distance_upper_bound=radius)
        kept = np.isfinite(distances)
        if kept.sum() < MIN_POINTS or kept.mean() > FOCUS_SHARE:
            return self
        out = copy.copy(self)
        raw = self._egi(self._target_normals[kept])
        out.target_coefficients = self._smoothed_levels(raw)
        out._normals_centre = self._target_normal_points[kept].mean(axis=0)
        return out

    def visible_points(
        self, moving: MovingCloud, rotation: ArrayLike, translation: ArrayLike
    ) -> NDArray[np.float64]:
        """The moving cloud's points at the pose ``x -> R (x - c) + c + T`` that face the
        fixed cloud's sensor (all of them when it is not a single view), shape (K, 3)."""
        R = np.asarray(rotation, dtype=np.float64)
        return self._visible(moving, R, np.asarray(translation, dtype=np.float64))[0]

    @property
    def target_normal_points(self) -> NDArray[np.float64]:
        """The fixed cloud's down-sampled points that carry its EGI normals (K, 3), metres."""
        return self._target_normal_points

    @property
    def target_normals(self) -> NDArray[np.float64]:
        """Unit normals (K, 3) at :attr:`target_normal_points`."""
        return self._target_normals

    @property
    def levels(self) -> int:
        """Number of EGI smoothing levels (``option.egi_smoothing``)."""
        return len(self.option.egi_smoothing)

    def reset(self) -> None:
        """Start again from the coarsest smoothing level, and from the global search
        when ``option.rotation_search`` is ``"global"`` (for a new servoing run)."""
        self.level = 0
        self.searching = self.option.rotation_search == "global"
        self._turned = np.eye(3)  # the law's turn since the handover (global search)

    # -- preparation -------------------------------------------------------------------
    def _prepare(self, cloud: object, name: str) -> PreparedCloud:
        arrays = as_arrays(cloud, name)
        extent = float(np.max(np.ptp(arrays.points, axis=0)))
        if extent < 4 * self.voxel_size:
            raise ValueError(
                f"{name} spans {extent:.4g} m, under 4 voxels of {self.voxel_size} m: use a "
                "smaller voxel_size (check the clouds are in metres)"
            )
        return prepare(
            arrays,
            self.voxel_size,
            egi_voxel_size=self.option.egi_voxel_size,
            normal_radius=self.option.normal_radius,
            camera_location=self.option.camera_location,
            name=name,
        )

    def _egi(
        self, normals: NDArray[np.float64], weights: NDArray[np.float64] | None = None
    ) -> NDArray[np.float64]:
        return egi_coefficients(
            normals, self.option.bandwidth, weights=weights, binned=self.option.egi_binned
        )

    def _smooth(self, raw: NDArray[np.float64], level: int) -> NDArray[np.float64]:
        return normalise(smooth(raw, self.option.egi_smoothing[level]))

    def _smoothed_levels(self, raw: NDArray[np.float64]) -> list[NDArray[np.float64]]:
        """Fixed-cloud EGI coefficients at every smoothing level."""
        return [self._smooth(raw, level) for level in range(self.levels)]

    def moving(
        self, cloud: object, name: str = "source", *, transformation: ArrayLike | None = None
    ) -> MovingCloud:
        """Prepare a moving cloud: down-sample, normals, EGI coefficients.

        Parameters
        ----------
        cloud : PointCloud, tensor PointCloud or ndarray (N, 3) / (N, 6)
            Metres; not modified.
        name : str
            Argument name for error messages.
        transformation : array_like, shape (4, 4), optional
            Rigid transform applied after preparation (normals are estimated in the
            cloud's own frame first).
        """
        prepared = self._prepare(cloud, name)
        points, point_normals, normals = prepared.points, prepared.point_normals, prepared.normals
        if transformation is not None:
            M = np.asarray(transformation, dtype=np.float64)
            points = points @ M[:3, :3].T + M[:3, 3]
            point_normals, normals = point_normals @ M[:3, :3].T, normals @ M[:3, :3].T
        centroid = points.mean(axis=0)
        radius = float(np.max(np.linalg.norm(points - centroid, axis=1)))
        return MovingCloud(points, point_normals, centroid, radius, self._egi(normals))

    # -- translation -------------------------------------------------------------------
    def _moving_box(self, moving: MovingCloud, centre: NDArray[np.float64]) -> Box:
        side = next_fast_len(int(np.ceil(2.0 * moving.radius / self.voxel_size)) + 4)
        half = side / 2.0 * self.voxel_size
        offset = np.floor((centre - half - self.lattice.origin) / self.voxel_size)
        return Box(self.lattice, offset.astype(np.int64), (side, side, side))

    def _fft_shape(self, fixed: Box, moving: Box) -> tuple[int, int, int]:
        return tuple(next_fast_len(a + b) for a, b in zip(fixed.shape, moving.shape, strict=True))

    def fft_shape(self, moving: MovingCloud) -> tuple[int, int, int]:
        """Shape of the FFT grid on which ``moving`` is correlated with the whole fixed cloud."""
        return self._fft_shape(self.target_box, self._moving_box(moving, moving.centroid))

    def search_box(self, moving: MovingCloud, around: ArrayLike | None = None) -> Box:
        """The block of the fixed grid that ``moving`` is phase-correlated with.

        The whole fixed grid when ``around`` is None or ``option.translation_window`` is
        None (a global translation search). Otherwise a cube of the moving grid's side
        plus ``translation_window`` voxels on each side, centred near ``around`` (metres,
        where the moving cloud's centroid is expected: snapped to a coarse step so that
        nearby predictions share one block and its cached spectrum), when its FFT is less
        than half the whole grid's.
        """
        margin = self.option.translation_window
        if around is None or margin is None:
            return self.target_box
        moving_box = self._moving_box(moving, moving.centroid)
        side = moving_box.shape[0] + 2 * margin
        snap = max(margin // 2, 1)
        centre = (np.asarray(around, dtype=np.float64) - self.lattice.origin) / self.voxel_size
        offset = (np.round(centre / snap) * snap).astype(np.int64) - side // 2
        window = Box(self.lattice, offset, (side, side, side))
        whole = np.prod(self._fft_shape(self.target_box, moving_box), dtype=np.float64)
        windowed = np.prod(self._fft_shape(window, moving_box), dtype=np.float64)
        return window if windowed < 0.5 * whole else self.target_box

    def _fixed_grid(self, box: Box) -> NDArray[np.float64]:
        """The unit-norm fixed grid on ``box`` (zero outside the fixed cloud's box)."""
        if box is self.target_box:
            return self._target_grid
        out = np.zeros(box.shape)
        lo = np.maximum(box.offset, self.target_box.offset)
        hi = np.minimum(box.offset + box.shape, self.target_box.offset + self.target_box.shape)
        if np.all(hi > lo):
            a, b = lo - box.offset, hi - box.offset
            c, d = lo - self.target_box.offset, hi - self.target_box.offset
            out[a[0] : b[0], a[1] : b[1], a[2] : b[2]] = self._target_grid[
                c[0] : d[0], c[1] : d[1], c[2] : d[2]
            ]
        return out

    def _fft(
        self, fixed: Box, moving: Box
    ) -> tuple[RealFFT3, NDArray[np.complexfloating]]:
        """The FFT plan for correlating ``moving`` with ``fixed``, and the fixed block's
        spectrum (cached: a few blocks and shapes recur over a registration)."""
        shape = self._fft_shape(fixed, moving)
        key = (tuple(fixed.offset), fixed.shape, shape)
        if key not in self._target_spectra:
            if len(self._target_spectra) >= 8:  # servoing meets many shapes: keep the last few
                del self._target_spectra[next(iter(self._target_spectra))]
            check_memory(shape, self.option.max_grid_memory, "voxel grids")
            fft = self._plan(shape)
            padded = np.zeros(shape, dtype=fft.dtype)
            f = fixed.shape
            padded[: f[0], : f[1], : f[2]] = self._fixed_grid(fixed)
            self._target_spectra[key] = np.array(fft.forward(padded))
        return self._plan(shape), self._target_spectra[key]

    def _plan(self, shape: tuple[int, int, int]) -> RealFFT3:
        return fft_plan(
            shape, planning=self.option.fft_planning, precision=self.option.fft_precision
        )

    def _translation_cost(self, grid: NDArray[np.float64], box: Box) -> float:
        """``J_t = 1/2 ||g - f||^2`` of unit-norm grids on the shared lattice; ``grid`` is
        the moving grid on ``box``, possibly zero-padded beyond it."""
        grid = grid[: box.shape[0], : box.shape[1], : box.shape[2]]
        q = box.offset - self.target_box.offset
        t_shape, m_shape = np.asarray(self.target_box.shape), np.asarray(box.shape)
        lo, hi = np.maximum(q, 0), np.minimum(q + m_shape, t_shape)
        overlap = 0.0
        if np.all(hi > lo):
            g = self._target_grid[lo[0] : hi[0], lo[1] : hi[1], lo[2] : hi[2]]
            a, b = lo - q, hi - q
            overlap = float(np.sum(g * grid[a[0] : b[0], a[1] : b[1], a[2] : b[2]]))
        return 1.0 - overlap  # 1/2 (|g|^2 + |f|^2) - <g, f> with |g| = |f| = 1

    # -- the law -----------------------------------------------------------------------
    def _visible(
        self, moving: MovingCloud, R: NDArray[np.float64], T: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_] | None, NDArray[np.float64] | None]:
        """The moving cloud's points at the pose, less those facing away from the fixed
        cloud's sensor when it is a single view; the mask and the cosines of incidence
        (None when nothing is culled)."""
        moved = moving.posed(R, T)
        if self.viewpoint is None:
            return moved, None, None
        rays = self.viewpoint - moved
        cosine = np.einsum("ij,ij->i", moving.point_normals @ R.T, rays)
        cosine /= np.maximum(np.linalg.norm(rays, axis=1), 1e-12)
        facing = cosine > 0.0
        if facing.sum() < MIN_POINTS:
            return moved, None, None
        return moved[facing], facing, cosine

    def _phase_correlate(
        self,
        moving: MovingCloud,
        moved: NDArray[np.float64],
        centre: NDArray[np.float64],
        around: ArrayLike | None,
    ) -> tuple[NDArray[np.float64], float, NDArray[np.floating], Box]:
        """Voxelise ``moved`` (the moving cloud's points, centroid at ``centre``) on the
        shared lattice and phase-correlate it with the fixed grid (eq.
        fourier_shift_solution): the shift (metres) onto the fixed cloud, the peak height,
        the unit-norm moving grid (zero-padded FFT buffer) and its box."""
        box = self._moving_box(moving, centre)
        fixed = self.search_box(moving, around)
        fft, G = self._fft(fixed, box)
        buffer = np.zeros(fft.shape, dtype=fft.dtype)
        splat(moved, box, mode=self.option.voxel_weighting, out=buffer)
        buffer /= np.linalg.norm(buffer)
        peak = cross_power_peak(
            fft.forward(buffer), G, fft, sigma=self.option.peak_width, positive_below=fixed.shape
        )
        shift = (fixed.offset - box.offset + peak.shift) * self.voxel_size
        return shift, peak.peak, buffer, box

    def locate(
        self, moving: MovingCloud, rotation: ArrayLike, *, around: ArrayLike | None = None
    ) -> tuple[NDArray[np.float64], float]:
        """Where the moving cloud, turned by ``rotation`` about its centroid, best matches
        the fixed one: the translation half of :meth:`evaluate`, without the rotation's.

        Parameters
        ----------
        moving : MovingCloud
        rotation : array_like, shape (3, 3)
        around : array_like, shape (3,), optional
            Search near this expected centroid (metres) only (:meth:`search_box`).

        Returns
        -------
        centre : ndarray, shape (3,)
            Where the moving cloud's centroid should go, metres.
        peak : float
            Height of the phase-correlation peak in [0, 1].
        """
        centre, peak, _ = self._locate(moving, np.asarray(rotation, dtype=np.float64), around)
        return centre, peak

    def _locate(
        self, moving: MovingCloud, R: NDArray[np.float64], around: ArrayLike | None
    ) -> tuple[NDArray[np.float64], float, float]:
        """:meth:`locate`, and the translation cost ``J_t`` before the shift."""
        moved, _, _ = self._visible(moving, R, np.zeros(3))
        shift, peak, buffer, box = self._phase_correlate(moving, moved, moving.centroid, around)
        return moving.centroid + shift, peak, self._translation_cost(buffer, box)

    def hypotheses(
        self,
        moving: MovingCloud,
        *,
        around: ArrayLike | None = None,
        level: int = -1,
        rotations: ArrayLike | None = None,
    ) -> list[Hypothesis]:
        """The ``option.hypotheses`` highest peaks of ``C_r`` over SO(3), placed and scored.

        ``C_r`` is evaluated on a grid of Euler angles (:meth:`rotation_grid`); each peak's
        rotation is located by phase correlation (:meth:`locate`, near ``around`` when
        given) and scored by ``option.hypothesis_score``.

        Parameters
        ----------
        moving : MovingCloud
        around : array_like, shape (3,), optional
            Expected centroid, metres.
        level : int
            EGI smoothing level of the correlation.
        rotations : array_like, shape (K, 3, 3), optional
            Rotations to place and score instead of the correlation's peaks.

        Returns
        -------
        list of Hypothesis
            Best score first.
        """
        if rotations is None:
            grid = self.rotation_grid(moving, level)
            rotations = [R for R, _ in peaks(grid, count=self.option.hypotheses)]
        found = []
        for R in np.asarray(rotations, dtype=np.float64).reshape(-1, 3, 3):
            centre, peak, cost = self._locate(moving, R, around)
            found.append(Hypothesis(R, centre, peak, cost, self.score(moving, R, centre, peak)))
        return sorted(found, key=lambda h: -h.score)

    def rotation_grid(self, moving: MovingCloud, level: int = -1) -> CorrelationGrid:
        """The rotation correlation over the whole of SO(3), on ``option.search_samples``
        samples of each ZYZ Euler angle, by SO(3) Fourier transforms.

        Against a single view (:attr:`viewpoint` known) with ``option.search_visibility``,
        the moving EGI as the sensor would see it turned: weighted by the cosine of
        incidence from where the sensor is seen from the fixed cloud's normals (their
        centroid), and normalised over that visible part
        (:func:`o3d_spectral.so3fft.visible_correlation_grid`), the correlation the law
        climbs there. Otherwise the plain ``C_r`` of the whole EGIs
        (:func:`o3d_spectral.so3fft.correlation_grid`).

        Parameters
        ----------
        moving : MovingCloud
        level : int
            EGI smoothing level.

        Returns
        -------
        CorrelationGrid
        """
        samples = self.option.search_samples or 4 * self.option.bandwidth
        G = self.target_coefficients[level]
        if self.viewpoint is None or not self.option.search_visibility:
            F = self._smooth(moving.coefficients, level)
            return correlation_grid(F, G, n_alpha=samples, n_beta=samples)
        F = smooth(moving.coefficients, self.option.egi_smoothing[level])
        sensor = facing(self.viewpoint - self._normals_centre)
        return visible_correlation_grid(F, G, sensor, n_alpha=samples, n_beta=samples)

    def score(
        self, moving: MovingCloud, rotation: ArrayLike, centre: ArrayLike, peak: float
    ) -> float:
        """How well a pose fits, by ``option.hypothesis_score``: the phase-correlation
        peak ``peak``, or the fitness with the moving cloud turned by ``rotation`` and its
        centroid at ``centre`` (metres)."""
        if self.option.hypothesis_score == "translation_peak":
            return peak
        return self.fitness(moving, rotation, np.asarray(centre) - moving.centroid)

    def evaluate(
        self,
        moving: MovingCloud,
        rotation: ArrayLike | None = None,
        translation: ArrayLike | None = None,
        *,
        level: int = -1,
        around: ArrayLike | None = None,
    ) -> Evaluation:
        """Full corrections for the moving cloud at pose ``(rotation, translation)``.

        Parameters
        ----------
        moving : MovingCloud
            From :meth:`moving`.
        rotation : array_like, shape (3, 3), optional
            ``R`` (identity when omitted).
        translation : array_like, shape (3,), optional
            ``T``, metres (zero when omitted). The pose maps ``x`` to
            ``R (x - c) + c + T``.
        level : int
            EGI smoothing level (index into ``option.egi_smoothing``; the finest by default).
        around : array_like, shape (3,), optional
            Where the moving cloud's centroid is expected (metres, e.g. the previous
            evaluation's prediction): the translation is then searched in a window of the
            fixed grid around it (:meth:`search_box`); anywhere when omitted.
        """
        R = np.eye(3) if rotation is None else np.asarray(rotation, dtype=np.float64)
        T = np.zeros(3) if translation is None else np.asarray(translation, dtype=np.float64)
        moved, facing, cosine = self._visible(moving, R, T)
        raw_egi = moving.coefficients
        if facing is not None:
            # A sensor samples a surface in proportion to its projected area: cos(incidence).
            raw_egi = self._egi(moving.point_normals[facing], cosine[facing])
        shift, peak, buffer, box = self._phase_correlate(moving, moved, moving.centroid + T, around)
        cost_t = self._translation_cost(buffer, box)
        # Rotation: gradient of the EGI correlation, scaled to an angle.
        F, G = self._smooth(raw_egi, level), self.target_coefficients[level]
        local = gradient(F, G, R)
        scale = curvature_scale(F, G)
        step = rotation_step(local, scale, preconditioned=self.option.preconditioned)
        return _evaluation(shift, step, local, peak, cost_t)

    def increments(self, evaluation: Evaluation) -> tuple[NDArray, NDArray]:
        """Apply the gains: ``(exp(lambda_r hat(step)), lambda_t grad_glob T)``.

        The rotation increment is capped at ``option.max_rotation_step`` radians.
        """
        w = self.option.lambda_r * evaluation.rotation
        angle = float(np.linalg.norm(w))
        if angle > self.option.max_rotation_step:
            w *= self.option.max_rotation_step / angle
        return so3.exp(w), self.option.lambda_t * evaluation.translation

    def rotation_spectra(
        self, moving: MovingCloud, level: int = -1
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Smoothed, normalised EGI coefficients ``(F, G)`` of the moving (whole, unculled)
        and the fixed cloud at a smoothing level, shape (B, 2B - 1) each."""
        return self._smooth(moving.coefficients, level), self.target_coefficients[level]

    def next_level(self, level: int, evaluation: Evaluation) -> int:
        """The smoothing level to use after ``evaluation`` (made at ``level``): the next
        finer one once the rotation step is below ``option.smoothing_switch``."""
        small = np.linalg.norm(evaluation.rotation) < self.option.smoothing_switch
        return level + 1 if small and level < self.levels - 1 else level

    def fitness(
        self, moving: MovingCloud, rotation: ArrayLike, translation: ArrayLike
    ) -> float:
        """Share of the moving cloud's voxels within one voxel of a fixed-cloud voxel.

        Open3D's ``fitness`` on the down-sampled clouds, at the pose ``x -> R (x - c) + c + T``;
        used to rank rotation hypotheses.
        """
        moved = moving.posed(np.asarray(rotation, dtype=np.float64), translation)
        distances, _ = self._target_tree.query(moved, distance_upper_bound=self.voxel_size)
        return float(np.mean(np.isfinite(distances)))

    def step(self, cloud: object) -> Step:
        """One control cycle for a freshly captured cloud (paper, Algorithm 1, loop body).

        With ``option.rotation_search="global"``, the first cycles head for the best of
        :meth:`hypotheses` (the whole of SO(3) searched again on each capture, the gains
        applied to its full correction) until it lies within ``option.handover_angle``
        of the identity; the law then takes over (:attr:`searching` turns False), until
        its increments add up to a turn over ``option.law_reach`` (it has left the
        basin it was handed: the search starts again). The law
        uses the current smoothing level (:attr:`level`) and moves to the next finer one
        once the rotation step is small; :meth:`reset` starts again.

        Parameters
        ----------
        cloud : PointCloud, tensor PointCloud or ndarray (N, 3) / (N, 6)
            The current cloud, in the same frame as the fixed one; not modified.

        Returns
        -------
        Step
        """
        moving = self.moving(cloud, "cloud")
        if self.searching:
            evaluation = self._towards_best_hypothesis(moving)
            if evaluation is not None:
                return Step(*self.increments(evaluation), moving.centroid, evaluation)
            self.searching = False
        evaluation = self.evaluate(moving, level=self.level)
        self.level = self.next_level(self.level, evaluation)
        delta_rotation, delta_translation = self.increments(evaluation)
        if self.option.rotation_search == "global":
            self._turned = delta_rotation @ self._turned
            if so3.rotation_angle(self._turned) > self.option.law_reach:
                self.reset()  # the law has left the hypothesis' basin: search again
        return Step(delta_rotation, delta_translation, moving.centroid, evaluation)

    def _towards_best_hypothesis(self, moving: MovingCloud) -> Evaluation | None:
        """Full corrections to the best of :meth:`hypotheses` (its rotation and where the
        phase correlation puts the turned cloud), or None when its rotation is within
        ``option.handover_angle`` of the identity (the local law's turn)."""
        best = self.hypotheses(moving)[0]
        rotation = so3.log(best.rotation)
        if np.linalg.norm(rotation) <= self.option.handover_angle:
            return None
        local = gradient(*self.rotation_spectra(moving), best.rotation)
        return _evaluation(
            best.centre - moving.centroid, rotation, local, best.translation_peak,
            best.cost_translation,
        )
