"""Settings of the spectral method, in the style of Open3D's ``*Option`` and
``*ConvergenceCriteria`` classes (frozen dataclasses with a readable ``repr``)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .grid import SPLAT_MODES

__all__ = ["SpectralRegistrationOption", "SpectralConvergenceCriteria"]


@dataclass(frozen=True)
class SpectralRegistrationOption:
    """How the clouds are represented and how the control law moves.

    Attributes
    ----------
    bandwidth : int
        ``B``: spherical harmonics of degree ``0 <= l < B`` (the paper's sum, its
        ``B = 16``); the EGI grid is ``2B x 2B``. See ``docs/conventions.md`` for the
        paper's ambiguous ``l_max = 32``.
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
    rotation_search : {"local", "global"}
        ``"local"``: the paper's gradient ascent from ``init``. ``"global"``: evaluate the
        rotation correlation over all of SO(3) (:mod:`o3d_spectral.so3fft`); place its
        ``hypotheses`` highest peaks and ``sampled_rotations`` more where the phase
        correlation puts the turned cloud (:meth:`o3d_spectral.SpectralStepper.locate`)
        and score the best placed; climb the ``climbs`` best for
        ``hypothesis_iterations``; climb the best of those on to convergence; return the
        best-scoring iterate of all the climbs (its score: ``hypothesis_score`` times
        its EGI correlation; with ``rank_refined``, the score after ``refinement``). In
        :meth:`o3d_spectral.SpectralStepper.step` (visual servoing): head for the best
        located peak, searched again on each capture, until it is within
        ``handover_angle`` of the identity, then apply the local law.
    hypotheses : int
        Peaks of the global correlation tried.
    climbs : int
        Hypotheses climbed after they have been located and scored.
    hypothesis_iterations : int
        Iterations of the law from each climbed hypothesis before they are ranked again.
    egi_focus : bool
        Global search in a scene larger than the moving cloud: once the first hypotheses
        have located it, match its EGI against the fixed cloud's normals around that
        place only (:meth:`o3d_spectral.SpectralStepper.focused`) and add that
        correlation's peaks to the hypotheses; each climbed hypothesis then matches only
        the fixed cloud's normals near its own points. No effect when the fixed cloud is
        about the moving cloud's size.
    focus_places : int
        With ``egi_focus``: how many places the EGI is focused on, the best distinct
        places (over the moving cloud's radius apart) where the first hypotheses put the
        moving cloud; each adds its own correlation's peaks. In a cluttered scene the
        best whole-scene hypothesis often lies on another object.
    search_visibility : bool
        Global search against a single view (``target_viewpoint``): correlate the fixed
        EGI with the moving one as the sensor would see it at each rotation (weighted by
        the cosine of incidence, normalised over its visible part,
        :meth:`o3d_spectral.SpectralStepper.rotation_grid`) rather than with the whole
        moving EGI, where rotations that turn the moving cloud's largest faces towards
        the sensor score high whatever the view holds.
    hypothesis_score : {"translation_peak", "fitness"}
        How hypotheses are ranked: the height of their phase-correlation peak (how well
        the rotated moving grid matches the fixed one under any shift; spectral, no
        nearest neighbours), or Open3D's fitness on the down-sampled clouds at the
        rotation and the translation the correlation found. After their climb, either
        is multiplied by the EGI correlation there (``4 pi C_r`` in [-1, 1]): a pose
        must match both the shape and the normals.
    sampled_rotations : int
        Global search: rotations spread evenly over SO(3)
        (:func:`o3d_spectral.so3.uniform_samples`) added to the correlation's peaks as
        candidates. Where part of either cloud is missing (occlusion, a scene) the
        EGI's peaks may all be far from the right rotation while the voxels still match
        there. 0: the EGI's peaks alone.
    placement_coarsening : int
        Global search: every candidate rotation (the correlation's peaks and the
        ``sampled_rotations``) is first placed by phase correlation on a grid this many
        times coarser (``placement_coarsening**3`` times fewer voxels); the
        ``placed_again`` with the highest peaks are placed again, and scored, on the
        full grid near there. 1 (default): every candidate placed on the full grid
        (needed with many ``sampled_rotations``). 2 takes a cluttered scene's search to
        about 0.65 of its time but locates the object less often there (52.5% against
        56.7% of the cluttered suite, issue 5's notes).
    placed_again : int
        Candidates placed again on the full grid (at least ``climbs``); with
        ``placement_coarsening=1`` and no ``sampled_rotations``, every peak is placed
        once, on the full grid, and this is not used.
    rank_refined : bool
        Global search: refine each climb's best iterate (``refinement``) and rank them
        by their score there, rather than refine the best-scoring iterate alone. A few
        degrees off, a sharp phase-correlation peak is low; compared polished, the
        right pose stands out more often.
    search_samples : int or None
        Samples of each Euler angle in the global grid (``4 * bandwidth`` when None:
        steps of 180 / (2B) degrees in alpha and gamma).
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
    refinement : {"point_to_plane", None}
        Polish of the law's final pose. ``"point_to_plane"`` (default): Open3D's
        point-to-plane ICP on the full clouds with correspondences up to
        ``0.4 * voxel_size``, the refinement of Open3D's global-registration tutorial
        (and of this project's FPFH baselines); its correspondences reach 0.4 voxel, so
        it polishes the law's pose rather than replacing it. Where the polished pose
        keeps at most half of the law's inliers at 0.4 voxel (the ICP slid off the
        surface from a wrong pose), the law's pose is returned. None: the spectral
        law's pose itself, with no correspondences at all (the paper).
    refinement_wide_distance : float or None
        With ``refinement``: the ICP is also run after a first pass with
        correspondences up to this many voxels (a wider basin: a mug a few degrees off
        about its axis, whose handle lies beyond 0.4 voxel), and the result that fits
        better (Open3D's fitness at 0.4 voxel) is kept. None: the 0.4-voxel ICP alone
        (the tutorial's, as the harness' FPFH baselines run it).
    max_correspondence_distance : float or None
        Distance (metres) at which ``fitness``, ``inlier_rmse`` and
        ``correspondence_set`` of the result are measured; the voxel size when None.
    normal_radius : float or None
        Search radius (metres) for normals estimated when a cloud has none;
        ``2.5 * voxel_size`` when None.
    camera_location : tuple of 3 float or None
        Where the sensor was (in the clouds' frame), to orient estimated normals.
    target_viewpoint : "auto", tuple of 3 float, or None
        Where the sensor that saw the target was (metres, target frame). When set, only
        the source points whose normals face it at the current pose take part (back-face
        culling), so that the back of a model is not matched against a one-sided scan.
        ``"auto"``: the origin, when at least 90% of the target's normals face it (a
        single view in its sensor's frame); None: never cull.
    max_grid_memory : float
        Largest memory (bytes) the voxel grids and their FFTs may take.
    fft_planning : {"estimate", "measure"}
        FFTW planning effort (:class:`o3d_spectral.fft.RealFFT3`): ``"measure"`` pays
        off over hundreds of iterations on one grid shape (visual servoing).
    fft_precision : {"single", "double"}
        Precision of the voxel grids' FFTs; single halves their time.
    handover_angle : float
        Visual servoing with ``rotation_search="global"``: the law takes over once the
        best hypothesis' rotation is this close to the identity, radians.
    law_reach : float
        Visual servoing with ``rotation_search="global"``: when the law's increments
        since the handover add up to a turn larger than this (radians), the global
        search starts again.
    """

    bandwidth: int = 16
    lambda_t: float = 0.5
    lambda_r: float = 0.5
    preconditioned: bool = True
    rotation_search: str = "local"
    hypotheses: int = 32
    climbs: int = 4
    hypothesis_iterations: int = 12
    hypothesis_score: str = "translation_peak"
    egi_focus: bool = True
    focus_places: int = 3
    search_visibility: bool = True
    sampled_rotations: int = 0
    placement_coarsening: int = 1
    placed_again: int = 8
    rank_refined: bool = False
    search_samples: int | None = None
    max_rotation_step: float = 0.35
    egi_binned: bool = False
    egi_smoothing: tuple[float, ...] = (0.3, 0.1)
    smoothing_switch: float = 0.05
    egi_voxel_size: float | None = None
    voxel_weighting: str = "trilinear"
    peak_width: float = 1.0
    translation_window: int | None = 8
    refinement: str | None = "point_to_plane"
    refinement_wide_distance: float | None = 1.0
    max_correspondence_distance: float | None = None
    normal_radius: float | None = None
    camera_location: tuple[float, float, float] | None = None
    target_viewpoint: str | tuple[float, float, float] | None = "auto"
    max_grid_memory: float = 2.0 * 2**30
    fft_planning: str = "estimate"
    fft_precision: str = "single"
    handover_angle: float = np.deg2rad(3.0)
    law_reach: float = np.deg2rad(15.0)

    def __post_init__(self) -> None:
        if int(self.bandwidth) != self.bandwidth or not 2 <= self.bandwidth <= 128:
            raise ValueError(f"bandwidth must be an integer in [2, 128], got {self.bandwidth}")
        for name in ("lambda_t", "lambda_r"):
            value = getattr(self, name)
            if not 0.0 < value <= 1.0:
                raise ValueError(f"{name} must be in (0, 1], got {value}")
        if self.voxel_weighting not in SPLAT_MODES:
            raise ValueError(
                f"voxel_weighting must be one of {SPLAT_MODES}, got {self.voxel_weighting!r}"
            )
        for name in ("max_rotation_step", "smoothing_switch", "peak_width", "max_grid_memory",
                     "handover_angle", "law_reach"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be positive, got {getattr(self, name)}")
        if self.rotation_search not in ("local", "global"):
            raise ValueError(
                f"rotation_search must be 'local' or 'global', got {self.rotation_search!r}"
            )
        if int(self.hypotheses) != self.hypotheses or self.hypotheses < 2:
            raise ValueError(f"hypotheses must be an integer >= 2, got {self.hypotheses}")
        if int(self.climbs) != self.climbs or not 1 <= self.climbs <= self.hypotheses:
            raise ValueError(
                f"climbs must be an integer in [1, hypotheses], got {self.climbs}"
            )
        if self.hypothesis_score not in ("translation_peak", "fitness"):
            raise ValueError(
                "hypothesis_score must be 'translation_peak' or 'fitness', got "
                f"{self.hypothesis_score!r}"
            )
        if self.hypothesis_iterations < 1:
            raise ValueError(
                f"hypothesis_iterations must be >= 1, got {self.hypothesis_iterations}"
            )
        if int(self.sampled_rotations) != self.sampled_rotations or self.sampled_rotations < 0:
            raise ValueError(
                f"sampled_rotations must be an integer >= 0, got {self.sampled_rotations}"
            )
        coarsening = self.placement_coarsening
        if int(coarsening) != coarsening or coarsening < 1:
            raise ValueError(
                f"placement_coarsening must be an integer >= 1, got {self.placement_coarsening}"
            )
        if int(self.focus_places) != self.focus_places or self.focus_places < 1:
            raise ValueError(f"focus_places must be an integer >= 1, got {self.focus_places}")
        if int(self.placed_again) != self.placed_again or self.placed_again < self.climbs:
            raise ValueError(
                f"placed_again must be an integer >= climbs ({self.climbs}), got "
                f"{self.placed_again}"
            )
        if self.search_samples is not None and self.search_samples < 2 * self.bandwidth - 1:
            raise ValueError(
                f"search_samples must be >= 2 * bandwidth - 1, got {self.search_samples}"
            )
        if isinstance(self.target_viewpoint, str) and self.target_viewpoint != "auto":
            raise ValueError(
                f"target_viewpoint must be 'auto', a point or None, got {self.target_viewpoint!r}"
            )
        if self.refinement not in (None, "point_to_plane"):
            raise ValueError(
                f"refinement must be None or 'point_to_plane', got {self.refinement!r}"
            )
        if self.refinement_wide_distance is not None and not (
            np.isfinite(self.refinement_wide_distance) and self.refinement_wide_distance > 0
        ):
            raise ValueError(
                "refinement_wide_distance must be a positive number of voxels or None, got "
                f"{self.refinement_wide_distance}"
            )
        if self.translation_window is not None and not (
            int(self.translation_window) == self.translation_window and self.translation_window >= 2
        ):
            raise ValueError(
                f"translation_window must be an integer >= 2 or None, got {self.translation_window}"
            )
        if self.fft_planning not in ("estimate", "measure"):
            raise ValueError(
                f"fft_planning must be 'estimate' or 'measure', got {self.fft_planning!r}"
            )
        if self.fft_precision not in ("single", "double"):
            raise ValueError(
                f"fft_precision must be 'single' or 'double', got {self.fft_precision!r}"
            )
        smoothing = tuple(float(s) for s in np.atleast_1d(self.egi_smoothing))
        if not smoothing or not all(s >= 0 for s in smoothing):
            raise ValueError(f"egi_smoothing must be widths >= 0, got {self.egi_smoothing}")
        object.__setattr__(self, "egi_smoothing", smoothing)
        if self.egi_voxel_size is not None and not self.egi_voxel_size > 0:
            raise ValueError(f"egi_voxel_size must be positive, got {self.egi_voxel_size}")


@dataclass(frozen=True)
class SpectralConvergenceCriteria:
    """When the control law stops (eq. updaterule).

    The paper stops when ``||grad_glob T|| + ||grad C_r|| < eps_g``, adding metres to
    correlation units. Here each term has its own tolerance in its own unit: iterations
    stop when the full translation correction is below ``translation_tolerance`` *and*
    the full rotation step is below ``rotation_tolerance``.

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
        if int(self.max_iteration) != self.max_iteration or self.max_iteration < 1:
            raise ValueError(f"max_iteration must be a positive integer, got {self.max_iteration}")
        if self.translation_tolerance is not None and not self.translation_tolerance > 0:
            raise ValueError(
                f"translation_tolerance must be positive, got {self.translation_tolerance}"
            )
        if not self.rotation_tolerance > 0:
            raise ValueError(f"rotation_tolerance must be positive, got {self.rotation_tolerance}")
