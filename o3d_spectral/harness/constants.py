"""Numeric constants of the evaluation harness, by the module using them."""

import numpy as np

# -- harness._plotting: the harness's plots ------------------------------------------------

#: Resolution of every plot (pixels per inch).
DPI = 110
#: Smallest error drawn on log axes (deg, mm).
FLOOR = 1e-3

#: Room on the right for a legend outside the panels, inches.
LEGEND_ROOM = 2.0


# -- harness.baselines: Open3D's methods as baselines --------------------------------------

#: ICP from the identity: correspondences up to this many voxels away, at most this many
#: iterations (Open3D's default 30 stops before a 10 cm offset is closed).
ICP_DISTANCE_VOXELS = 5.0
ICP_MAX_ITERATION = 100

#: FGR's options: the correspondence distance in voxels, Open3D's defaults for the rest.
FGR_DISTANCE_VOXELS = 0.5


# -- harness.bop: BOP datasets -------------------------------------------------------------

#: Voxel (m) the whole frame is down-sampled to (the bundled YCB-Video frame's 2 mm).
FRAME_VOXEL = 0.002
#: Least visible fraction of an annotated object that BOP evaluates.
MIN_VISIBLE = 0.1


# -- harness.converters: the real data as benchmark folders --------------------------------

#: The frame's image size (rows, columns), pixels.
IMAGE_SHAPE = (480, 640)
#: Octree depth of the screened Poisson reconstruction of a model surface.
POISSON_DEPTH = 7
#: Surface vertices farther than this (metres) from every model point are removed.
POISSON_TRIM = 0.01
#: Largest distance (pixels) of a point's image from integer pixel coordinates: float32
#: coordinates keep a point's image within 1e-4 px of its pixel.
PIXEL_TOLERANCE = 1e-3


# -- harness.executors: where an evaluation runs -------------------------------------------

#: How often (seconds) a pool worker checks that the process that started it is alive.
PARENT_POLL = 0.5
#: How often (seconds) the pool's parent checks for an interrupt while it waits for rows.
INTERRUPT_POLL = 0.2


# -- harness.figures: an evaluation's plots ------------------------------------------------

#: Bins of the initial rotation (degrees) in the success-against-angle plot: 20 degrees
#: wide from 0 to 180, the range of the suites' rotations.
ANGLE_BINS_DEG = np.arange(0.0, 181.0, 20.0)


# -- harness.metrics: per-instance metrics -------------------------------------------------

#: Distance (m) within which an observed point counts as lying on a posed model: about
#: three times the suites' depth noise at 1 m (1.9 mm), over their 3 mm depth step.
OBSERVATION_TOLERANCE = 0.005


# -- harness.pairs: scan pairs in the 3DMatch layout ---------------------------------------

#: Registration recall's thresholds: rotation and translation errors (FCGF, DGR) ...
RECALL_ROTATION_DEG, RECALL_TRANSLATION_M = 15.0, 0.30
#: ... and the benchmark's own, on the correspondences' RMSE (Choi et al. 2015).
MAX_RMSE_M = 0.2
#: How far from symmetric, relative to its largest entry, and how negative, relative to
#: its largest eigenvalue, an information matrix may be: ten significant digits written.
INFORMATION_TOLERANCE = 1e-6


# -- harness.pose_metrics: BOP's pose-error metrics ----------------------------------------

#: VSD's misalignment tolerance of the visibility test (m), BOP's 15 mm.
VSD_DELTA_M = 0.015
#: VSD's tolerances of a pixel's distance error, as fractions of the object's diameter.
VSD_TAUS = tuple(round(0.05 * k, 2) for k in range(1, 11))
#: VSD error below which an estimate is correct (for each of :data:`VSD_TAUS`).
VSD_THRESHOLDS = tuple(round(0.05 * k, 2) for k in range(1, 11))
#: MSSD error below which an estimate is correct, as fractions of the diameter.
MSSD_THRESHOLDS = tuple(round(0.05 * k, 2) for k in range(1, 11))
#: MSPD error below which an estimate is correct (pixels of a 640-pixel-wide image).
MSPD_THRESHOLDS_PX = tuple(float(5 * k) for k in range(1, 11))
#: Rotations a continuous symmetry is sampled at: BOP's ``ceil(pi / 0.01)`` over a turn.
CONTINUOUS_STEPS = int(np.ceil(np.pi / 0.01))


# -- harness.real: the real cases ----------------------------------------------------------

#: Turntable angles (degrees) of the bundled dragon scans.
DRAGON_ANGLES: tuple[int, ...] = tuple(range(0, 169, 24))

#: Voxel size (metres) of the dragon's scans at any step: the dragon is 0.2 m across.
DRAGON_VOXEL = 0.005

#: Success: symmetry-aware rotation error under 5 degrees and translation error (at the
#: source's centroid) under 1 cm (:func:`case_errors`).
MAX_ROTATION_DEG, MAX_TRANSLATION_M = 5.0, 0.01
#: Where the dragon scanner looked from, in every scan's frame: far along +z (the scans'
#: normals facing it agree with the scans' neighbours; checked in tests/test_real.py).
DRAGON_SENSOR = (0.0, 0.0, 10.0)


# -- harness.selection: which instances run ------------------------------------------------

#: Instances with ``index % TUNING_MODULUS == 0`` form the tuning split: settings tuned on
#: them (``eval/tune_fpfh.py``) are reported on the other instances only.
TUNING_MODULUS = 4
