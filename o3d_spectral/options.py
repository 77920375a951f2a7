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
class GlobalSearchOption:
    """The search over all of SO(3) (:func:`o3d_spectral.registration_spectral_global`).

    The EGIs' rotation correlation is sampled on a grid of ZYZ Euler angles; its peaks
    (and, between two scans, the shells' and the sweep's candidates) are placed by phase
    correlation and scored by its peak height; the best is confirmed by a short ICP
    (``confirm``) or else the ``climbs`` best are climbed by the law and the best-scoring
    iterate is returned (``docs/method.md``). The defaults are the measured choice
    (``docs/design-notes.md``): lower ``hypotheses``, ``climbs`` or ``sweep_rotations``
    only to trade success for time, and set ``workers`` to share the machine.

    Attributes
    ----------
    hypotheses : int, default 32
        Peaks of the rotation correlation placed, >= 2.
    climbs : int, default 4
        Placed hypotheses climbed by the law, 1 to ``hypotheses``.
    hypothesis_iterations : int, default 12
        Iterations of the law from each climbed hypothesis before they are ranked again,
        >= 1.
    egi_focus : bool, default True
        In a fixed cloud larger than the moving one (a scene): also correlate the moving
        EGI with the fixed cloud's normals around the places the first hypotheses put
        it, add those correlations' peaks, and let each climb match only the fixed
        normals near its own points. No effect when the clouds are about one size.
    focus_places : int, default 3
        With ``egi_focus``: the number of places the EGI is focused on, >= 1, the best
        distinct places (over the moving cloud's radius apart) of the first hypotheses.
    scene_hypotheses : int, default 16
        In a scene (a fixed cloud over 1.5 times the moving one's radius) searched with
        ``egi_focus``: the whole EGI's highest peaks placed over the whole scene to find
        the focus places, >= 1. Each costs a phase correlation on the whole scene's grid.
    search_visibility : bool, default True
        Against a single view (``CloudOption.target_viewpoint``): correlate the fixed
        EGI with the moving one as the sensor would see it at each rotation (weighted by
        the cosine of incidence, normalised over its visible part). False: with the
        whole moving EGI.
    search_samples : int or None, default None
        Samples of each Euler angle in the rotation grid, >= ``2 * bandwidth - 1``;
        None: ``4 * bandwidth`` (steps of 180 / (2B) degrees in alpha and gamma). Memory
        grows with its cube (:meth:`check_memory`).
    shell_hypotheses : int, default 32
        Between two single views (two scans): peaks of the correlation of the voxel
        grids' spectra on spherical shells tried besides the EGI's, >= 0; 0 tries none.
    sweep_rotations : int, default 1000
        Between two single views: rotations spread evenly over SO(3), >= 0 (those that
        keep the two sensors within 110 degrees are tried), placed on a coarse grid, the
        best 16 kept as more candidates; 0 tries none.
    confirm : bool, default True
        Polish the best placed hypothesis by a short point-to-plane ICP and, where its
        fit shows it clearly right, return it without the climbs (not in a scene), so
        easy cases end early. False: always climb.
    peak_ascent : bool, default True
        Between two single views: turn the best pose to where the phase correlation's
        peak is highest before the polish (the law's EGI term sees only what each
        sensor saw and leaves such poses degrees off). Not applied to a model against a
        view or a scene.
    coarse_placements : int, default 16
        Between two single views: the candidates (about 80) are first placed on a grid
        of twice the voxel (an eighth of the FFT) and only this many, the highest, are
        placed at full resolution, >= 0; 0 places every one at full resolution. Not
        applied to a model against a view or a scene.
    second_opinions : int, default 0
        Where the pose the search returns may be wrong (its calibrated confidence under
        one half, after the climbs), up to this many of the other climbs' poses, distinct
        from it, are climbed on to convergence, polished and measured, and the most
        confident result is returned, >= 0; 0 never. Each costs about a local
        registration; calls whose pose is not in doubt pay nothing. More calls end right
        (3: 4 more of 146 bench calls), but the confidence of a result chosen as the most
        confident of several is no longer calibrated: wrong poses so chosen are warned
        less often (the warning's recall 0.91 -> 0.78 on the calibration's held-back
        calls), hence off by default.
    turns : int, default 12
        Where the returned pose may be wrong (its calibrated confidence under one half)
        and the motion its inliers resist least is a turn they barely hold (two views of
        a mug, whose body fits at any turn about its axis and whose handle then misses),
        the pose is turned about that axis in this many even steps, the turns polished
        briefly and the best two polished and measured whole; the most confident result
        whose inliers hold every motion is returned, >= 0; 0 never. Not in a scene (a
        turned object finds other surfaces to fit there). Calls whose pose is not in
        doubt pay nothing; the others 0.03-0.6 s on the bench.
    workers : int or None, default None
        Threads the independent parts of the search run on, >= 1 (placements, the
        sweep's batches, the confirmation's polishes, the climbs, the ascent's starts);
        None: every core, as Open3D's RANSAC (at most ``OMP_NUM_THREADS`` when set). The
        result is the same to the bit whatever the count.
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
    second_opinions: int = 0
    turns: int = 12
    workers: int | None = None

    def __post_init__(self) -> None:
        check_int("hypotheses", self.hypotheses, low=2)
        check_int("shell_hypotheses", self.shell_hypotheses, low=0)
        check_int("coarse_placements", self.coarse_placements, low=0)
        check_int("sweep_rotations", self.sweep_rotations, low=0)
        check_int("second_opinions", self.second_opinions, low=0)
        check_int("turns", self.turns, low=0)
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
    """The point-to-plane ICP polish of the law's final pose.

    Open3D's point-to-plane ICP on the full clouds, with correspondences up to
    ``distance`` voxels, optionally also after a first, wider pass; the result with the
    higher fitness at ``distance`` is kept, unless it slid off the surface (keeping at
    most half of the law's inliers), when the law's pose is returned. Pass
    ``refinement=None`` to the registration calls for the law's pose alone.

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
