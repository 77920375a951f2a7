"""Numeric constants of the evidence on a pose, by the module using them."""

import numpy as np

# -- evidence.confidence: the calibrated confidence ----------------------------------------
# Calibrated on: the development groups of eval/calibrate_confidence.py (the run that fitted
#   the model is named in docs/data/sources.json); its figures held out by object and by
#   group in docs/errors.md
# Measured again by: python eval/calibrate_confidence.py --out RUN --per-group 24, then
#   --rows RUN/rows.csv --split object and --split group
# Trades: WARN_BELOW lower: fewer right poses warned, more wrong ones silent

#: The pose may be wrong below this confidence (the odds are against it).
WARN_BELOW = 0.5
#: Shares are clipped to [SHARE_CLIP, 1 - SHARE_CLIP] before their logit.
SHARE_CLIP = 0.02
#: Added to the plane distance (voxels) before its logarithm.
PLANE_FLOOR = 1e-3

# Fitted by eval/calibrate_confidence.py (see the module docstring): command, data and
# commit in docs/data/sources.json ("calibrate_confidence_summary"); the same numbers in
# docs/data/calibrate_confidence_coefficients.json.
#: The logistic model's intercept.
BIAS = 2.9884
#: The logistic model's coefficient of each feature (raw units).
COEFFICIENTS = {
    "logit_fit_object": 2.0328,
    "logit_fit_views": -0.2754,
    "two_views": 5.1068,
    "logit_target_fit": -0.2489,
    "log_plane_object": -1.1498,
    "log_plane_views": -0.8628,
    "logit_normals_object": 1.9444,
    "sqrt_free_space": -43.8222,
    "sensor_known": -2.2904,
    "ambiguous_different": -0.7524,
    "support_gap": 2.0803,
}


# -- evidence.diagnostics: the warnings ----------------------------------------------------

#: A cloud whose mean unit normal is at least this long is flat (:attr:`CloudReading.flatness`).
FLAT = 0.97


# -- evidence.fit: a pose's fit after a short polish ---------------------------------------
# Calibrated on: as the early stop: the view suites' instances 0-47 and the dragon pairs
# Measured again by: python eval/bench_speed.py --suites SUITES --limit 6 --rotations 1
#   --repeats 3
# Trades: a closer distance tells a near-symmetric pose from the right one, until it reads
#   the sensor's noise as misfit

#: The closeness's distance, voxels. At one voxel a near-symmetric wrong pose fits within
#: 0.01 of the right one or better (a box turned half a turn); at a quarter voxel the three
#: wrong poses that were placed best were 0.044-0.058 less close than a right rival, and
#: right poses led wrong rivals by 0.008 or more (once trailed, by 0.012: no early stop).
CLOSE_DISTANCE = 0.25
#: The short polish's correspondence distances, voxels: a wide pass to take the placed
#: pose (a few degrees off, on the Euler grid) into the basin, then one at the fit's.
ICP_DISTANCES = (2.0, 1.0)


# -- evidence.free_motions: the motions a pose's overlap leaves free -----------------------
# Calibrated on: exact cases (tests/test_free_motions.py) and the calibration's groups
# Measured again by: python eval/calibrate_confidence.py --out RUN --per-group 24, then
#   --rows RUN/rows.csv --split object and --split group
# Trades: a higher support floor or a shorter tolerance names more free motions, and warns
#   about more right poses

#: A motion whose constraint is under this share of the mean constraint over the six
#: motions is not resisted by the points. A view that shows only a body of revolution (a
#: mug's body with its handle hidden, a can, a bowl) leaves the turn about its axis at
#: 0.2-0.6% of the mean on the bundled models' views; a view showing the mug's handle
#: holds it with 15-26%, and a box's or a drill's views every motion with 2% or more.
SUPPORT_FLOOR = 0.01
#: A free motion goes on while the moved inliers' median distance to the target's
#: tangent planes stays within this many voxels of the pose's own (a quarter of the
#: inlier distance: a motion the surface resists moves the median inlier by half a voxel
#: across it within a voxel's travel).
PLANE_SLACK = 0.25
#: A free motion goes on while at least this share of the inliers stays over the
#: target's surface (most of the overlap still overlaps: what leaves it moves where the
#: target shows nothing, which neither holds nor contradicts the motion).
STAYING = 0.5
#: A pose is right within 5 degrees and 1 cm (:mod:`o3d_spectral.evidence.confidence`): a turn
#: that goes farther than this either way, in degrees, in all, leaves the pose unfixed.
TURN_TOLERANCE = 5.0
#: A slide that goes farther than this many voxels, both ways together, leaves the pose
#: unfixed (1 cm at the calibration's 8 mm voxel, each way).
SLIDE_TOLERANCE = 2.5
#: A free motion whose rotation (scaled by the inliers' RMS radius) is under this share
#: of the motion is a slide; the free motions' rotations span the turns, their null
#: space the slides.
SLIDE_ROTATION = 0.05
#: A slide is followed at most this many times the inliers' largest distance to their
#: centroid either way (twice their width: past it, they could stay over a target only
#: twice their size).
SLIDE_REACH = 4.0
#: Steps either way at most: a turn's half turn, or a slide's reach, in even steps of a
#: voxel at the farthest inlier, or this many where those would be more.
MAX_STEPS = 48


# -- evidence.pose: the pose's evidence ----------------------------------------------------

#: Normals closer than this (degrees, either sign) agree.
NORMAL_AGREEMENT_ANGLE = 30.0
#: A source point violates the free space when the nearest target point on its ray lies
#: more than this many voxels behind it (the sensor saw through it).
FREE_SPACE_DEPTH = 2.0
#: Half-width of a ray, in voxels at the source point's range: target points within it
#: are on the ray.
RAY_RADIUS = 0.5
#: The free-space test counts the source points whose normal makes a cosine over this
#: with their ray to the sensor: at grazing rays a depth sensor returns no point on the
#: surface, and a right pose's silhouette would seem seen through.
MIN_INCIDENCE = 0.2
#: Target points looked at on each ray, nearest to it first (one point per voxel puts
#: a few on a ray: its front and back surfaces).
RAY_NEIGHBOURS = 8


# -- evidence.poses: distinct poses --------------------------------------------------------

#: Rotations further apart than this (radians) are distinct poses: the confirmation's
#: rivals, the confidence's runner-up, the verification's rivals.
DISTINCT_ANGLE = np.deg2rad(10.0)


# -- evidence.verification: the returned pose against its rivals ---------------------------
# Calibrated on: the calibration's groups (eval/calibrate_confidence.py)
# Measured again by: python eval/calibrate_confidence.py --out RUN --per-group 24, then
#   --rows RUN/rows.csv --split object and --split group
# Trades: a wider ambiguity margin warns about more right poses; a narrower one leaves
#   rivals that fit as well unsaid

#: Hypotheses measured at most, besides the returned pose.
RIVALS = 4
#: A distinct pose whose fit is at least the returned pose's less this makes the pose
#: ambiguous (a fit counts points within one voxel: 0.02 is one point in fifty).
AMBIGUITY_MARGIN = 0.02
#: A pose that fits less than this is not called ambiguous (a wrong pose is not made
#: more or less right by a rival that fits as poorly).
AMBIGUITY_MIN_FIT = 0.5
#: The turns of the returned pose tried as rivals, degrees about each principal axis
#: (a box, a can or a bottle maps onto itself, or nearly, by some of them).
TURN_ANGLES = (90.0, 180.0, -90.0)
#: The best turn, fitting within this of the pose before any polish, is polished.
TURN_POLISH = 0.3
#: The turns are measured on the fixed points within this many voxels of the ball of
#: the posed moving points (the short ICP's 2 voxels, and 2 of drift).
TURN_REACH = 4.0
#: A rival whose turn from the returned pose moves the source's points this far (median,
#: voxels) from its own surface or more is a different pose, not a symmetry.
ASYMMETRIC = 0.15
#: A tree of the fixed points serves a region this many times the ball of the posed points
#: and its fit's distance (:class:`FixedPoints`): room for the turns and polished rivals
#: about the same centroid, which then need no tree of their own.
REGION_SLACK = 1.5
#: Where a region would hold more than this share of the fixed cloud, one tree of the whole
#: cloud serves every fit instead (two views of one object).
WHOLE_SHARE = 0.5
