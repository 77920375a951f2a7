"""Settings of the spectral method, in the style of Open3D's ``*Option`` and
``*ConvergenceCriteria`` classes: frozen dataclasses with defaults and a readable ``repr``.

- :class:`SpectralRegistrationOption`: the two representations and the control law;
- :class:`CloudOption`: how the input clouds are read (normals, where the sensors were);
- :class:`RefinementOption`: the point-to-plane polish of the final pose;
- :class:`SpectralConvergenceCriteria`: when the law stops.

Every field is checked on construction (:mod:`o3d_spectral.common.checks`): a wrong type raises
``TypeError``, a NaN or out-of-range value ``ValueError``, each naming the field and the
value.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .common.checks import check_bool, check_choice, check_int, check_number, check_point
from .spectra.grid import SPLAT_MODES

__all__ = [
    "SpectralRegistrationOption",
    "CloudOption",
    "RefinementOption",
    "SpectralConvergenceCriteria",
]


@dataclass(frozen=True)
class SpectralRegistrationOption:
    """How the clouds are represented and how the control law moves.

    :meth:`paper` gives the paper's choices; ``bandwidth`` trades rotation resolution for
    time; ``max_grid_memory`` bounds what one call may allocate.

    Attributes
    ----------
    bandwidth : int, default 16
        ``B``, 2 to 128: spherical harmonics of degree ``0 <= l < B`` (the paper's
        ``B = 16``). The EGI grid is ``2B x 2B``, the global search's rotation grid
        ``(4B)^3``; time and memory grow with ``B^3``. See ``docs/conventions.md``.
    lambda_t : float, default 0.5
        Translation gain in (0, 1]: the fraction of the phase-correlation shift applied
        per iteration (the paper's eq. control_law).
    lambda_r : float, default 0.5
        Rotation gain in (0, 1]: the fraction of the rotation step applied per iteration.
        The gradient is divided by the correlation's curvature, so the step is an angle
        and one gain fits every cloud.
    preconditioned : bool, default True
        True: divide the rotation gradient by the curvature axis by axis (a damped Newton
        step). False: by its mean (the paper's plain gradient, scaled).
    max_rotation_step : float, default 0.35
        Largest rotation applied in one iteration, radians, > 0.
    egi_binned : bool, default False
        True: the EGI is the paper's histogram on the ``2B x 2B`` grid. False: the
        normals are projected onto the harmonics exactly (no binning error).
    egi_smoothing : tuple of float, default (0.3, 0.1)
        Widths of the heat kernel smoothing the EGI, radians, >= 0, coarse to fine, at
        least one (a single number is accepted). A wide kernel gives the rotation
        correlation a wide basin, a narrow one a sharp peak; the law starts at the first
        width and moves on when its rotation step falls below ``smoothing_switch``.
    smoothing_switch : float, default 0.05
        Rotation step, radians, > 0, below which the law moves to the next, finer
        smoothing.
    egi_voxel_size : float or None, default None
        Cell, metres, > 0, in which normals are averaged before the EGI is built; None:
        ``voxel_size / 4``.
    voxel_weighting : {"trilinear", "count", "binary"}, default "trilinear"
        How points fill the voxel grid: each point shared among its 8 nearest voxel
        centres (continuous in the points' positions, needed for sub-voxel shifts), the
        number of points per voxel, or 1 for every occupied voxel (the paper's).
    peak_width : float, default 1.0
        Width, voxels, > 0, of the Gaussian window fitted to the phase-correlation peak
        for the sub-voxel shift.
    translation_window : int or None, default 8
        Margin, voxels, >= 2: after a climb's first, whole-grid phase correlation, only
        the block of the fixed grid this far around where the last correlation put the
        moving cloud is correlated. Applied only where it makes the FFT under half as
        large (a small object in a large scene). None: the whole fixed grid every
        iteration (the paper's).
    max_grid_memory : float, default 2 GiB
        Bytes, > 0: the most one voxel grid's FFT buffers, or the global search's SO(3)
        correlation grid, may take; a call that needs more raises ``ValueError`` before
        any work. Raise it for fine voxels on large scenes.
    """

    bandwidth: int = 16
    lambda_t: float = 0.5
    lambda_r: float = 0.5
    preconditioned: bool = True
    max_rotation_step: float = 0.35
    egi_binned: bool = False
    egi_smoothing: tuple[float, ...] = (0.3, 0.1)
    smoothing_switch: float = 0.05
    egi_voxel_size: float | None = None
    voxel_weighting: str = "trilinear"
    peak_width: float = 1.0
    translation_window: int | None = 8
    max_grid_memory: float = 2.0 * 2**30

    def __post_init__(self) -> None:
        check_int("bandwidth", self.bandwidth, low=2, high=128)
        for name in ("lambda_t", "lambda_r"):
            check_number(name, getattr(self, name), low=0.0, high=1.0, low_open=True)
        for name in ("preconditioned", "egi_binned"):
            check_bool(name, getattr(self, name))
        for name in ("max_rotation_step", "smoothing_switch", "peak_width", "max_grid_memory"):
            check_number(name, getattr(self, name), low=0.0, low_open=True)
        check_number("egi_voxel_size", self.egi_voxel_size, low=0.0, low_open=True, optional=True)
        check_choice("voxel_weighting", self.voxel_weighting, SPLAT_MODES)
        check_int("translation_window", self.translation_window, low=2, optional=True)
        if isinstance(self.egi_smoothing, str):
            raise TypeError(f"egi_smoothing must be widths in radians, got {self.egi_smoothing!r}")
        smoothing = tuple(np.atleast_1d(self.egi_smoothing).tolist())
        if not smoothing:
            raise ValueError("egi_smoothing must hold at least one width, got ()")
        for width in smoothing:
            check_number("egi_smoothing", width, low=0.0)
        object.__setattr__(self, "egi_smoothing", tuple(float(s) for s in smoothing))

    @classmethod
    def paper(cls) -> SpectralRegistrationOption:
        """The paper's choices: a binary voxel grid, the binned EGI histogram, the plain
        (scaled) gradient, one smoothing level and the whole grid searched every
        iteration."""
        return cls(
            voxel_weighting="binary", egi_binned=True, preconditioned=False,
            egi_smoothing=(0.1,), translation_window=None,
        )


@dataclass(frozen=True)
class CloudOption:
    """How the input clouds are read: their normals and where their sensors were.

    Change it when the clouds carry no normals and their sensors' positions are known
    (``camera_location``, ``source_camera_location``), or to turn back-face culling off
    (``target_viewpoint=None``).

    Attributes
    ----------
    normal_radius : float or None, default None
        Search radius, metres, > 0, for the normals estimated when a cloud has none;
        None: ``2.5 * voxel_size``.
    camera_location : tuple of 3 float or None, default None
        Where the sensor was, metres, in the clouds' frame: estimated (or re-oriented)
        normals of the target, and of the source unless ``source_camera_location`` is
        given, are turned towards it.
    target_viewpoint : "auto", tuple of 3 float, or None, default "auto"
        Where the sensor that saw the target was, metres, target frame. When set, only
        the source points whose normals face it at the current pose take part
        (back-face culling), so the back of a model is not matched against a one-sided
        scan. ``"auto"``: the origin when at least 90% of the target's normals face it
        (a single view in its sensor's frame), else far along the view direction
        recognised from the normals and depth
        (:func:`o3d_spectral.io.normals.view_direction`), else none. None: never cull.
    source_camera_location : tuple of 3 float or None, default None
        Where the source's sensor was, metres, source frame, when it differs from the
        target's (two scans taken from two places).
    """

    normal_radius: float | None = None
    camera_location: tuple[float, float, float] | None = None
    target_viewpoint: str | tuple[float, float, float] | None = "auto"
    source_camera_location: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        check_number("normal_radius", self.normal_radius, low=0.0, low_open=True, optional=True)
        for name in ("camera_location", "source_camera_location"):
            object.__setattr__(self, name, check_point(name, getattr(self, name)))
        if isinstance(self.target_viewpoint, str):
            check_choice("target_viewpoint", self.target_viewpoint, ("auto",))
        else:
            object.__setattr__(self, "target_viewpoint", check_point(
                "target_viewpoint", self.target_viewpoint))

    @property
    def source_camera(self) -> tuple[float, float, float] | None:
        """Where the source's sensor was (metres, source frame): ``source_camera_location``,
        or ``camera_location`` when it is not given."""
        if self.source_camera_location is not None:
            return self.source_camera_location
        return self.camera_location


@dataclass(frozen=True)
class RefinementOption:
    """The point-to-plane ICP polish of the law's final pose.

    Open3D's point-to-plane ICP on the full clouds (of a source over 100,000 points, that
    many evenly spread: ``o3d_spectral.refinement.constants.MAX_POLISH_POINTS``), with
    correspondences up to ``distance`` voxels, optionally also after a first, wider pass;
    the result with the higher fitness at ``distance`` is kept, unless it slid off the
    surface (keeping at most half of the law's inliers), when the law's pose is returned.
    Pass ``refinement=None`` to the registration calls for the law's pose alone.

    Attributes
    ----------
    distance : float, default 0.4
        Correspondence distance of the polish, voxels, > 0 (Open3D's global-registration
        tutorial uses 0.4).
    wide_distance : float or None, default 1.0
        Correspondence distance, voxels, > 0, of a first ICP pass whose result is
        polished as well: a wider basin, for poses a few degrees off (a mug's handle
        beyond 0.4 voxel). None: the polish alone (as the harness's FPFH baselines run
        it).
    cell : float or None, default None
        The polish reads both clouds one point per cube of this many voxels, > 0 (0.5:
        the resolution at which users tuning FPFH-RANSAC for speed polish its pose).
        None: every point.
    """

    distance: float = 0.4
    wide_distance: float | None = 1.0
    cell: float | None = None

    def __post_init__(self) -> None:
        check_number("distance", self.distance, low=0.0, low_open=True)
        check_number("wide_distance", self.wide_distance, low=0.0, low_open=True, optional=True)
        check_number("cell", self.cell, low=0.0, low_open=True, optional=True)


@dataclass(frozen=True)
class SpectralConvergenceCriteria:
    """When the control law stops (eq. updaterule).

    The paper stops when ``||grad_glob T|| + ||grad C_r|| < eps_g``, adding metres to
    correlation units. Here each term has its own tolerance in its own unit: the law
    stops, at the finest EGI smoothing, when the full translation correction is below
    ``translation_tolerance`` and the full rotation step below ``rotation_tolerance``,
    or after ``max_iteration`` iterations.

    Attributes
    ----------
    max_iteration : int, default 100
        Iterations at most, >= 1.
    translation_tolerance : float or None, default None
        Metres, > 0; None: ``0.02 * voxel_size``.
    rotation_tolerance : float, default 1e-3
        Radians, > 0.
    """

    max_iteration: int = 100
    translation_tolerance: float | None = None
    rotation_tolerance: float = 1e-3

    def __post_init__(self) -> None:
        check_int("max_iteration", self.max_iteration, low=1)
        check_number(
            "translation_tolerance", self.translation_tolerance, low=0.0, low_open=True,
            optional=True,
        )
        check_number("rotation_tolerance", self.rotation_tolerance, low=0.0, low_open=True)

    def tolerances(self, voxel_size: float) -> tuple[float, float]:
        """``(translation, rotation)`` tolerances, metres and radians."""
        return self.translation_tolerance or 0.02 * voxel_size, self.rotation_tolerance
