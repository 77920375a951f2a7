"""Settings of the spectral method, in the style of Open3D's ``*Option`` and
``*ConvergenceCriteria`` classes: frozen dataclasses with defaults and a readable ``repr``.

- :class:`SpectralRegistrationOption`: the two representations and the control law;
- :class:`CloudOption`: how the input clouds are read (normals, where the sensors were);
- :class:`GlobalSearchOption`: the search over all of SO(3)
  (:func:`o3d_spectral.registration_spectral_global`);
- :class:`RefinementOption`: the point-to-plane polish of the final pose;
- :class:`SpectralConvergenceCriteria`: when the law stops.

Every field is checked on construction (:mod:`o3d_spectral._checks`): a wrong type raises
``TypeError``, a NaN or out-of-range value ``ValueError``, each naming the field and the
value.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._checks import check_bool, check_choice, check_int, check_number, check_point
from .spectra.grid import SPLAT_MODES

__all__ = [
    "SpectralRegistrationOption",
    "CloudOption",
    "GlobalSearchOption",
    "RefinementOption",
    "SpectralConvergenceCriteria",
]


@dataclass(frozen=True)
class SpectralRegistrationOption:
    """How the clouds are represented and how the control law moves.

    Attributes
    ----------
    bandwidth : int
        ``B``: spherical harmonics of degree ``0 <= l < B`` (the paper's sum, its
        ``B = 16``); the EGI grid is ``2B x 2B``. See ``docs/conventions.md``.
    lambda_t : float
        Translation gain in (0, 1]: fraction of the phase-correlation shift applied per
        iteration (eq. control_law).
    lambda_r : float
        Rotation gain in (0, 1]: fraction of the rotation step applied per iteration. The
        gradient is divided by the correlation's curvature, so the step is an angle and
        one gain fits every cloud.
    preconditioned : bool
        Divide the rotation gradient by the local curvature axis by axis (a damped Newton
        step) rather than by its mean (the paper's plain gradient, scaled).
    max_rotation_step : float
        Largest rotation applied in one iteration, radians.
    egi_binned : bool
        Build the EGI as the paper's histogram on the ``2B x 2B`` grid (True) or project
        the normals exactly (False, default; no binning error).
    egi_smoothing : tuple of float
        Widths (radians) of the heat kernel smoothing the EGI, coarse to fine. A wide
        kernel gives the rotation correlation a wide basin; a narrow one a sharp peak.
        The law starts with the first and moves to the next when the rotation step falls
        below ``smoothing_switch``.
    smoothing_switch : float
        Rotation step (radians) below which the next, finer smoothing is used.
    egi_voxel_size : float or None
        Cell (metres) in which normals are averaged before the EGI is built;
        ``voxel_size / 4`` when None.
    voxel_weighting : {"trilinear", "count", "binary"}
        How points fill the voxel grid; ``"binary"`` is the paper's.
    peak_width : float
        Width of the Gaussian window of the phase correlation, voxels (sub-voxel fit).
    translation_window : int or None
        After the first, global, phase correlation of a climb, correlate against a block
        of the fixed grid around where the last correlation put the moving cloud, with
        this many voxels of margin on each side (used only where it makes the FFT under
        half as large: a small object in a large scene). None: the whole fixed grid every
        iteration (the paper).
    max_grid_memory : float
        Largest memory (bytes) one voxel grid's FFT buffers, or the global search's SO(3)
        correlation grid, may take.
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

    Attributes
    ----------
    normal_radius : float or None
        Search radius (metres) for normals estimated when a cloud has none;
        ``2.5 * voxel_size`` when None.
    camera_location : tuple of 3 float or None
        Where the sensor was (metres, in the clouds' frame), to orient normals estimated
        (or oriented again) for the target, and for the source unless
        ``source_camera_location`` is given.
    source_camera_location : tuple of 3 float or None
        Where the source's sensor was (metres, source frame), when it differs from the
        target's (two scans from two places).
    target_viewpoint : "auto", tuple of 3 float, or None
        Where the sensor that saw the target was (metres, target frame). When set, only
        the source points whose normals face it at the current pose take part (back-face
        culling), so that the back of a model is not matched against a one-sided scan.
        ``"auto"``: the origin, when at least 90% of the target's normals face it (a
        single view in its sensor's frame), else far along the direction of a view
        recognised from its normals and depth (:func:`o3d_spectral.io.normals.view_direction`),
        else none; None: never cull.
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
class GlobalSearchOption:
    """The search over all of SO(3) (:func:`o3d_spectral.registration_spectral_global`).

    The rotation correlation is evaluated on a grid of ZYZ Euler angles by SO(3) Fourier
    transforms; its ``hypotheses`` highest peaks are placed by phase correlation and
    scored by that correlation's peak height; the ``climbs`` best are climbed by the law
    for ``hypothesis_iterations`` and ranked again (peak height times EGI correlation);
    the best is climbed on to convergence, and the best-scoring iterate of all the climbs
    is returned (:mod:`o3d_spectral.search`).

    Attributes
    ----------
    hypotheses : int
        Peaks of the global correlation tried.
    climbs : int
        Hypotheses climbed after they have been located and scored.
    hypothesis_iterations : int
        Iterations of the law from each climbed hypothesis before they are ranked again.
    egi_focus : bool
        In a fixed cloud larger than the moving one (a scene), match the moving EGI
        against the fixed cloud's normals around the places the first hypotheses put it
        only, and add those correlations' peaks; each climb then matches only the fixed
        normals near its own points. No effect when the clouds are about one size.
    focus_places : int
        With ``egi_focus``: how many places the EGI is focused on, the best distinct
        places (over the moving cloud's radius apart) where the first hypotheses put it.
    scene_hypotheses : int
        In a scene (a fixed cloud over 1.5 times the moving one's radius,
        :meth:`o3d_spectral.spectra.target_grid.TargetGrid.holds_more`) searched with
        ``egi_focus``: how many of the whole EGI's highest peaks are placed over the whole
        scene. They only have to find the places the EGI is focused on, where the
        focused EGI's ``hypotheses`` peaks are placed; each costs a phase correlation on
        the whole scene's grid (about 13 ms on a tabletop). 16 succeed on cluttered
        scenes as often as 32 in less time, and more often on a real RGB-D frame, where
        more whole-scene peaks place the object on the clutter; 8 are too few.
    search_visibility : bool
        Against a single view (``CloudOption.target_viewpoint``): correlate the fixed EGI
        with the moving one as the sensor would see it at each rotation (weighted by the
        cosine of incidence, normalised over its visible part) rather than with the whole
        moving EGI.
    search_samples : int or None
        Samples of each Euler angle in the grid (``4 * bandwidth`` when None: steps of
        180 / (2B) degrees in alpha and gamma); at least ``2 * bandwidth - 1``.
    shell_hypotheses : int
        For two single views (two scans): peaks of the correlation of the voxel grids'
        spectra on spherical shells (:mod:`o3d_spectral.spectra.shells`) tried besides the EGI's;
        0 tries none.
    sweep_rotations : int
        For two single views: rotations spread evenly over SO(3) (this many over the
        whole of it; those that keep the two sensors within 110 degrees are tried) placed
        by phase correlation on a coarse grid, the best 16 then as the other candidates
        (:func:`o3d_spectral.search.swept_rotations`); 0 tries none.
    confirm : bool
        Confirm the best placed hypothesis by a short point-to-plane ICP and its fit
        (:mod:`o3d_spectral.confirmation`) and, where it is clearly right, skip the climbs:
        the search's effort then follows the difficulty of the case. False: always climb.
    peak_ascent : bool
        Between two single views, turn the best pose to where the phase correlation's
        peak is highest (:func:`o3d_spectral.ascent.peak_ascent`) before the polish: the
        law's EGI term, which sees only what each sensor saw, leaves it 8-20 degrees off
        there. Not elsewhere: on RGB-D crops of objects outside the tuning set it turned
        right poses of a box and a can half a turn.
    coarse_placements : int
        For two single views (two scans: :meth:`o3d_spectral.SpectralStepper.two_views`),
        the candidates (the EGI's, the shells' and the sweep's, about 80) are first placed
        on grids of twice the voxel (an eighth of the FFT) and only this many, the
        highest, are placed at full resolution; 0 places every one at full resolution.
        The coarse grid ranked a candidate within 10 degrees of the truth first or second
        on every dragon scan pair that had one (31 of 48); 16 leaves room for the near
        ties of a symmetric shape (a box's half turns). Against 32: the dragon pairs 43
        of 50 registered (42), synthetic view pairs of the twelve models 23 of 24 (22),
        23% less time. Not for a model against a view (it loses occluded views) or a
        scene (the coarse grid ranks clutter above the object).
    workers : int or None
        Threads the independent parts of the search are spread over (the placements and
        the sweep's, the confirmation's polishes, the climbs, the ascent's coarse starts);
        every core when None, as Open3D's RANSAC (at most ``OMP_NUM_THREADS`` when that
        is set). The result is the same to the bit whatever the count
        (:mod:`o3d_spectral.parallel`).
    """

    hypotheses: int = 32
    climbs: int = 4
    hypothesis_iterations: int = 12
    egi_focus: bool = True
    focus_places: int = 3
    scene_hypotheses: int = 16
    search_visibility: bool = True
    search_samples: int | None = None
    shell_hypotheses: int = 32
    sweep_rotations: int = 1000
    confirm: bool = True
    peak_ascent: bool = True
    coarse_placements: int = 16
    workers: int | None = None

    def __post_init__(self) -> None:
        check_int("hypotheses", self.hypotheses, low=2)
        check_int("shell_hypotheses", self.shell_hypotheses, low=0)
        check_int("coarse_placements", self.coarse_placements, low=0)
        check_int("sweep_rotations", self.sweep_rotations, low=0)
        check_int("climbs", self.climbs, low=1, high=self.hypotheses, high_name="hypotheses")
        for name in ("hypothesis_iterations", "focus_places", "scene_hypotheses"):
            check_int(name, getattr(self, name), low=1)
        for name in ("egi_focus", "search_visibility", "confirm", "peak_ascent"):
            check_bool(name, getattr(self, name))
        check_int("search_samples", self.search_samples, low=3, optional=True)
        check_int("workers", self.workers, low=1, optional=True)

    def check_memory(self, option: SpectralRegistrationOption) -> None:
        """``ValueError`` when the SO(3) correlation grid (complex, ``samples^3``, three
        transforms against a single view) would exceed ``option.max_grid_memory``."""
        samples = self.samples(option.bandwidth)
        need = 3.0 * 16.0 * float(samples) ** 3
        if need > option.max_grid_memory:
            raise ValueError(
                f"the global search's SO(3) grid of {samples}^3 rotations needs about "
                f"{need / 2**20:.0f} MiB, over max_grid_memory={option.max_grid_memory:.3g} "
                f"bytes: lower GlobalSearchOption.search_samples or the bandwidth "
                f"({option.bandwidth}), or raise max_grid_memory"
            )

    def samples(self, bandwidth: int) -> int:
        """Euler-angle samples per axis for ``bandwidth``; ``ValueError`` when too few."""
        samples = self.search_samples or 4 * bandwidth
        if samples < 2 * bandwidth - 1:
            raise ValueError(
                f"search_samples must be >= 2 * bandwidth - 1 = {2 * bandwidth - 1}, got "
                f"{samples}: raise it or lower the bandwidth"
            )
        return samples


@dataclass(frozen=True)
class RefinementOption:
    """The point-to-plane ICP polish of the law's final pose (:mod:`o3d_spectral.refinement`).

    Open3D's point-to-plane ICP on the full clouds with correspondences up to
    ``distance`` voxels (Open3D's global-registration tutorial uses 0.4), optionally after
    a first, wider pass; the result that fits better is kept, unless it slid off the
    surface (it keeps at most half of the law's inliers), when the law's pose is returned.

    Attributes
    ----------
    distance : float
        Correspondence distance of the polish, voxels.
    wide_distance : float or None
        Also run the polish after a first ICP with correspondences up to this many voxels
        (a wider basin: a mug a few degrees off about its axis, whose handle lies beyond
        0.4 voxel), and keep whichever has the higher fitness at ``distance``. None: the
        polish alone (the tutorial's, as the harness' FPFH baselines run it).
    """

    distance: float = 0.4
    wide_distance: float | None = 1.0

    def __post_init__(self) -> None:
        check_number("distance", self.distance, low=0.0, low_open=True)
        check_number("wide_distance", self.wide_distance, low=0.0, low_open=True, optional=True)


@dataclass(frozen=True)
class SpectralConvergenceCriteria:
    """When the control law stops (eq. updaterule).

    The paper stops when ``||grad_glob T|| + ||grad C_r|| < eps_g``, adding metres to
    correlation units. Here each term has its own tolerance in its own unit: iterations
    stop, at the finest EGI smoothing level, when the full translation correction is below
    ``translation_tolerance`` *and* the full rotation step is below ``rotation_tolerance``.

    Attributes
    ----------
    max_iteration : int
        Iterations at most.
    translation_tolerance : float or None
        Metres; ``0.02 * voxel_size`` when None.
    rotation_tolerance : float
        Radians.
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
