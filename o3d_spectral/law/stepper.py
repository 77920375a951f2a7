"""The fixed cloud's spectra, and one evaluation of the control law against them.

A :class:`SpectralStepper` holds what is computed once for the fixed cloud: its voxel grid
and cached spectra (:class:`o3d_spectral.spectra.target_grid.TargetGrid`) and its EGI's
spherical-harmonic coefficients at every smoothing level. For a moving cloud at a pose
``x -> R (x - c) + c + T`` (``c``: the moving cloud's centroid, the paper's rotation about
the centre of gravity) :meth:`SpectralStepper.evaluate` returns the full corrections:

- translation ``grad_glob T`` (metres): the phase-correlation shift that takes the moved
  cloud onto the fixed one (eq. fourier_shift_solution), sub-voxel;
- rotation (radians): ``grad C_r`` (eq. cr_derivative) divided by the correlation's
  curvature (:func:`o3d_spectral.spectra.rotation.rotation_step`),

and :meth:`SpectralStepper.increments` applies the gains (eq. control_law). The loop is
:mod:`o3d_spectral.law.loop`; a stepper holds no state of a run: it serves many moving clouds.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from ..common.checks import check_instance, check_voxel_size
from ..correlation.device import device_backend, parse_device
from ..io.cloud import MIN_POINTS, CloudReading, PreparedCloud, extent
from ..io.normals import sensor_position
from ..io.rows import lengths
from ..options import CloudOption, SpectralRegistrationOption
from ..spectra import so3
from ..spectra.egi import coefficients as egi_coefficients
from ..spectra.egi import facing, harmonics_table, normalise, smooth
from ..spectra.rotation import curvature_scale, gradient, rotation_step
from ..spectra.so3fft import CorrelationGrid, correlation_grid, visible_correlation_grid
from ..spectra.target_grid import TargetGrid
from .constants import FOCUS_SHARE, MAX_HARMONICS_TABLE
from .evaluation import Evaluation
from .prepared import prepared_cloud

__all__ = ["MovingCloud", "Evaluation", "SpectralStepper", "FOCUS_SHARE"]


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
    harmonics : ndarray, shape (M, B (2B - 1)), or None
        Real spherical harmonics at each of ``point_normals``
        (:func:`o3d_spectral.spectra.egi.harmonics_table`), kept when the fixed cloud is a
        single view: the visible part's EGI is then one product per pose.
    reading : CloudReading
        How the cloud was read: its normals' provenance, and ``view`` (turned with it).
    """

    points: NDArray[np.float64]
    point_normals: NDArray[np.float64]
    centroid: NDArray[np.float64]
    radius: float
    coefficients: NDArray[np.float64]
    harmonics: NDArray[np.float64] | None = None
    reading: CloudReading = CloudReading()

    def posed(self, rotation: NDArray[np.float64], translation: ArrayLike) -> NDArray[np.float64]:
        """The points at the pose ``x -> R (x - c) + c + T``, shape (M, 3)."""
        return (self.points - self.centroid) @ rotation.T + self.centroid + translation


class SpectralStepper:
    """Spectra of a fixed cloud, and the control law's corrections against them.

    Parameters
    ----------
    target : PointCloud, tensor PointCloud or ndarray (N, 3) / (N, 6)
        The fixed cloud (reference), metres. Not modified. Normals are estimated when
        absent (see :func:`o3d_spectral.io.cloud.prepare`).
    voxel_size : float
        Voxel edge ``r``, metres (the paper: 0.008).
    option : SpectralRegistrationOption, optional
    cloud : CloudOption, optional
        Normal estimation and the target's sensor position.
    frame_origin : array_like, shape (3,), optional
        Where the origin of the caller's frame lies in the clouds' frame (metres): the
        sensor of a scan given in its sensor's frame (``target_viewpoint="auto"``, depth
        maps). The origin when omitted; the registration calls pass it when they centre
        clouds given far from the origin.
    device : str or open3d.core.Device, optional
        Where the global search's batched correlations run (``"CPU:0"``, ``"CUDA:0"``:
        :mod:`o3d_spectral.correlation.device`); the law runs on the CPU.
    """

    def __init__(
        self, target: object, voxel_size: float, *,
        option: SpectralRegistrationOption | None = None, cloud: CloudOption | None = None,
        frame_origin: ArrayLike | None = None, device: object | None = None,
    ) -> None:
        voxel_size = check_voxel_size(voxel_size)
        check_instance("option", option, SpectralRegistrationOption)
        check_instance("cloud", cloud, CloudOption)
        self.device = parse_device(device)
        self.backend = device_backend(self.device)  # before any work: CUDA not usable
        self.option = option or SpectralRegistrationOption()
        self.cloud = cloud or CloudOption()
        self.voxel_size = float(voxel_size)
        self.frame_origin = np.zeros(3) + (0.0 if frame_origin is None else frame_origin)
        prepared = self._prepare(target, "target")
        self.grid = TargetGrid(
            prepared.points, self.voxel_size, weighting=self.option.voxel_weighting,
            peak_width=self.option.peak_width, window=self.option.translation_window,
            max_memory=self.option.max_grid_memory,
        )
        self.target_points = prepared.points
        self.target_normals, self.target_normal_points = prepared.normals, prepared.normal_points
        self.target_reading = prepared.reading
        self.normals_centre = prepared.normal_points.mean(axis=0)
        self.target_coefficients = self._smoothed_levels(
            self._egi(prepared.normals, two_sided=prepared.reading.two_sided)
        )
        self.viewpoint = self._viewpoint(prepared)

    @property
    def levels(self) -> int:
        """Number of EGI smoothing levels (``option.egi_smoothing``)."""
        return len(self.option.egi_smoothing)

    def _prepare(self, cloud: object, name: str, camera: ArrayLike | None = None
                 ) -> PreparedCloud:
        return prepared_cloud(
            cloud, self.voxel_size, egi_voxel_size=self.option.egi_voxel_size,
            normal_radius=self.cloud.normal_radius,
            camera_location=self.cloud.camera_location if camera is None else camera,
            origin=self.frame_origin, name=name,
        )

    @cached_property
    def normals_tree(self) -> cKDTree:
        """KD-tree of the fixed cloud's normal points (:attr:`target_normal_points`; for
        :meth:`focused` and the measure of the returned pose), built once."""
        return cKDTree(self.target_normal_points)

    def _viewpoint(self, target: PreparedCloud) -> NDArray[np.float64] | None:
        """Sensor position of a single-view target, or None (see ``target_viewpoint``;
        never found for a two-sided target, which is no view)."""
        choice = self.cloud.target_viewpoint
        if choice is None or not isinstance(choice, str):
            return None if choice is None else np.asarray(choice, dtype=np.float64)
        if target.reading.two_sided:
            return None
        return sensor_position(target.points, target.point_normals, target.reading.view,
                               self.frame_origin)

    def _egi(
        self, normals: NDArray[np.float64], weights: NDArray[np.float64] | None = None, *,
        two_sided: bool = False,
    ) -> NDArray[np.float64]:
        return egi_coefficients(
            normals, self.option.bandwidth, weights=weights, binned=self.option.egi_binned,
            two_sided=two_sided,
        )

    def _smooth(self, raw: NDArray[np.float64], level: int) -> NDArray[np.float64]:
        return normalise(smooth(raw, self.option.egi_smoothing[level]))

    def _smoothed_levels(self, raw: NDArray[np.float64]) -> list[NDArray[np.float64]]:
        return [self._smooth(raw, level) for level in range(self.levels)]  # every level

    def moving(
        self, cloud: object, name: str = "source", *, transformation: ArrayLike | None = None,
        prepared: PreparedCloud | None = None,
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
        prepared : PreparedCloud, optional
            ``cloud`` already down-sampled with its normals (:func:`prepared_cloud`, as
            :func:`o3d_spectral.prepare` keeps it): not prepared again.
        """
        if prepared is None:
            prepared = self._prepare(cloud, name, self.cloud.source_camera)
        points, point_normals, normals = prepared.points, prepared.point_normals, prepared.normals
        if transformation is not None:
            M = np.asarray(transformation, dtype=np.float64)
            points = points @ M[:3, :3].T + M[:3, 3]
            point_normals, normals = point_normals @ M[:3, :3].T, normals @ M[:3, :3].T
        reading = prepared.reading
        if transformation is not None:
            reading = reading.turned(M[:3, :3])
        centroid, radius = extent(points)
        B = self.option.bandwidth
        table = None
        fits = len(points) * B * (2 * B - 1) * 8 <= MAX_HARMONICS_TABLE
        if self._culls(reading) and not self.option.egi_binned and fits:
            table = harmonics_table(point_normals, B)
        F = self._egi(normals, two_sided=reading.two_sided)
        return MovingCloud(points, point_normals, centroid, radius, F, table, reading)

    def sees(self, moving: MovingCloud) -> bool:
        """Whether the moving cloud is matched as the fixed cloud's sensor would see it:
        the fixed cloud is a single view (:attr:`viewpoint`) and the moving cloud is not
        (two views each miss what the other sees: neither is culled)."""
        return self._culls(moving.reading)

    def _culls(self, reading: CloudReading) -> bool:
        """:meth:`sees` for a moving cloud read as ``reading``."""
        return self.viewpoint is not None and reading.view is None

    def focused(self, near: ArrayLike, radius: float) -> SpectralStepper:
        """This stepper with the fixed EGI made only of the fixed cloud's normals within
        ``radius`` (metres) of one of the points ``near`` (metres, shape (K, 3)).

        In a scene (a tabletop against one object's model) the whole EGI is dominated by
        the table and the other objects; once the moving cloud is located, the normals
        around it are those its EGI should match. The voxel grid is shared. ``self``
        when over ``FOCUS_SHARE`` of the normals are kept, or fewer than ``MIN_POINTS``.
        """
        near = np.asarray(near, dtype=np.float64).reshape(-1, 3)
        hits = self.normals_tree.query_ball_point(near, r=radius, return_sorted=False)
        kept = np.zeros(len(self.target_normal_points), dtype=bool)
        kept[np.concatenate([np.asarray(h, dtype=np.int64) for h in hits])] = True
        if kept.sum() < MIN_POINTS or kept.mean() > FOCUS_SHARE:
            return self
        out = copy.copy(self)
        focused = self._egi(self.target_normals[kept], two_sided=self.target_reading.two_sided)
        out.target_coefficients = self._smoothed_levels(focused)
        out.normals_centre = self.target_normal_points[kept].mean(axis=0)
        return out

    # -- the law -----------------------------------------------------------------------
    def visible(
        self, moving: MovingCloud, R: NDArray[np.float64], T: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_] | None, NDArray[np.float64] | None]:
        """The moving cloud's points at the pose ``x -> R (x - c) + c + T``, less those
        facing away from the fixed cloud's sensor when it is a single view; the mask and
        the cosines of incidence (None when nothing is culled). A two-sided cloud
        (:attr:`o3d_spectral.io.cloud.CloudReading.two_sided`) faces the sensor with either
        side: none of its points is culled, and a negative cosine says the sensor sees
        the side its normal points away from."""
        moved = moving.posed(R, T)
        if not self.sees(moving):
            return moved, None, None
        rays = self.viewpoint - moved
        cosine = np.einsum("ij,ij->i", moving.point_normals @ R.T, rays)
        cosine /= np.maximum(lengths(rays), 1e-12)
        toward = (cosine != 0.0) if moving.reading.two_sided else (cosine > 0.0)
        if toward.sum() < MIN_POINTS:
            return moved, None, None
        return moved[toward], toward, cosine

    def locate(
        self, moving: MovingCloud, rotation: ArrayLike, *, around: ArrayLike | None = None,
        factor: float = 1.0,
    ) -> tuple[NDArray[np.float64], float, float]:
        """Where the moving cloud, turned by ``rotation`` (3, 3) about its centroid, best
        matches the fixed one, searched near ``around`` (metres) when given, on a grid of
        ``factor`` voxels (:meth:`o3d_spectral.spectra.target_grid.TargetGrid.coarsened`):
        its centroid there (metres), the peak height and ``J_t`` before the shift."""
        moved, _, _ = self.visible(moving, np.asarray(rotation, dtype=np.float64), np.zeros(3))
        grid = self.grid.coarsened(factor)
        placed = grid.correlate(moved, moving.radius, moving.centroid, around)
        return moving.centroid + placed.shift, placed.peak, placed.cost

    def rotation_grid(
        self, moving: MovingCloud, samples: int, *, visibility: bool = True, level: int = -1
    ) -> CorrelationGrid:
        """The rotation correlation over the whole of SO(3), on ``samples`` samples of
        each ZYZ Euler angle, by SO(3) Fourier transforms, at an EGI smoothing level.

        Against a single view (:attr:`viewpoint` known) with ``visibility``, the moving
        EGI as the sensor would see it turned: weighted by the cosine of incidence from
        where the sensor is seen from the fixed cloud's normals (their centroid), and
        normalised over that visible part
        (:func:`o3d_spectral.spectra.so3fft.visible_correlation_grid`), the correlation the law
        climbs there. A two-sided moving cloud is seen the same way: each normal ``n``
        seen with weight ``|n . d|``, turned to face the sensor, is at ``m`` facing it
        ``(m . d) (f(m) + f(-m))``, twice the cosine-weighted two-sided EGI (its
        coefficients). Otherwise the plain ``C_r`` of the whole EGIs
        (:func:`o3d_spectral.spectra.so3fft.correlation_grid`).
        """
        G = self.target_coefficients[level]
        if not (visibility and self.sees(moving)):
            F = self._smooth(moving.coefficients, level)
            return correlation_grid(F, G, n_alpha=samples, n_beta=samples)
        F = smooth(moving.coefficients, self.option.egi_smoothing[level])
        sensor = facing(self.viewpoint - self.normals_centre)
        return visible_correlation_grid(F, G, sensor, n_alpha=samples, n_beta=samples)

    def evaluate(
        self, moving: MovingCloud, rotation: ArrayLike | None = None,
        translation: ArrayLike | None = None, *, level: int = -1, around: ArrayLike | None = None,
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
            fixed grid around it (:meth:`TargetGrid.search_box`); anywhere when omitted.
        """
        R = np.eye(3) if rotation is None else np.asarray(rotation, dtype=np.float64)
        T = np.zeros(3) if translation is None else np.asarray(translation, dtype=np.float64)
        moved, toward, cosine = self.visible(moving, R, T)
        raw_egi = moving.coefficients
        if toward is not None:
            # A sensor samples a surface in proportion to its projected area: cos(incidence).
            raw_egi = self._visible_egi(moving, toward, cosine[toward])
        placed = self.grid.correlate(moved, moving.radius, moving.centroid + T, around)
        # Rotation: gradient of the EGI correlation, scaled to an angle.
        F, G = self._smooth(raw_egi, level), self.target_coefficients[level]
        local = gradient(F, G, R)
        scale = curvature_scale(F, G)
        step = rotation_step(local, scale, preconditioned=self.option.preconditioned)
        return Evaluation.of(placed.shift, step, local, placed.peak, placed.cost)

    def _visible_egi(
        self, moving: MovingCloud, toward: NDArray[np.bool_], cosine: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """EGI coefficients of the moving cloud's point normals selected by ``toward``,
        each turned to face the sensor and weighted by the magnitude of its ``cosine`` of
        incidence (in the cloud's own frame: the pose turns them later). Only a two-sided
        cloud has negative cosines: its turned normals keep the even degrees of
        ``|cosine|`` and take the odd ones of ``cosine`` (``S_lm(-n) = (-1)^l S_lm(n)``)."""
        weights = np.abs(cosine)
        if moving.harmonics is None:
            facing = moving.point_normals[toward] * np.where(cosine < 0.0, -1.0, 1.0)[:, None]
            return self._egi(facing, weights)
        B = self.option.bandwidth
        F = (weights @ moving.harmonics[toward]).reshape(B, 2 * B - 1)
        if moving.reading.two_sided:
            F[1::2] = (cosine @ moving.harmonics[toward]).reshape(B, 2 * B - 1)[1::2]
        return F

    def increments(
        self, evaluation: Evaluation
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
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
