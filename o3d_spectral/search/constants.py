"""Numeric constants of the global search (``o3d_spectral.search``), by the module using them."""

import numpy as np

# -- search.ascent: the ascent of the phase-correlation peak -------------------------------
# Calibrated on: the dragon scans (44-54 voxels across) and 1.6 m RGB-D frames
# Measured again by: python eval/bench_real.py --out RUN --rotations 5 --workers 1
# Trades: finer steps and grids climb closer to the peak, for phase correlations

#: The compass search's steps, radians, largest first (each tried until no turn by it
#: raises the peak): from a pose 20 degrees off to within about 3 degrees, which the
#: point-to-plane polish takes on (dragon pairs: 0.3 s, about 55 phase correlations).
ASCENT_STEPS = tuple(np.deg2rad([8.0, 4.0, 2.0, 1.0]))
#: Cells the moving cloud spans at most on the ascent's grid: the voxel itself for the
#: dragon scans (44-54 voxels across); 2.5 voxels for a 1.6 m RGB-D frame at 1 cm, whose
#: 55 full-resolution correlations would take seconds.
ASCENT_SPAN = 64.0
#: :func:`best_ascent` first ascends every start on a grid where the moving cloud spans at
#: most this many cells (2 voxels for the dragon scans: an eighth of the FFT) ...
PRESELECT_SPAN = 32.0
#: ... with these steps (radians), enough to tell the starts apart.
PRESELECT_STEPS = tuple(np.deg2rad([8.0, 4.0]))


# -- search.candidates: the sweep between two scans ----------------------------------------
# Calibrated on: the dragon scans 48-96 degrees apart and the turntable pairs 45-135 degrees
#   apart
# Measured again by: python eval/bench_speed.py --suites SUITES --limit 6 --rotations 1
#   --repeats 3 --groups dragon_48 dragon_72 dragon_96 turntable_90 turntable_135
# Trades: a finer sweep grid or more rotations placed keep a true rotation farther from the
#   nearest swept one, for time

#: Voxels of the grid the sweep's rotations are first placed on: a 27th of the FFT; a true
#: rotation 10-15 degrees off the nearest swept one still placed best or nearly on the
#: dragon scans, 44-54 voxels across ...
SWEEP_FACTOR = 3.0
#: ... or more, so that the moving cloud spans at most this many of its cells: the cost of
#: each placement bounded whatever the clouds' size (two 1.6 m RGB-D frames at 1 cm).
SWEEP_SPAN = 18.0
#: The sweep's rotations that join the other candidates.
SWEEP_PLACEMENTS = 16
#: The sweep ranks its rotations first on a grid this many times coarser again (a quarter
#: of the FFT's cells there, 20-27 cells a side on the dragon scans) ...
SWEEP_PRESELECT_FACTOR = 2.0
#: ... and places only this many best of them on its own grid: the dragon pairs 24-120
#: degrees apart and the turntable pairs 45-135 degrees apart (two rotations each, 78
#: pairs) keep the same 16 best and the same poses, at 0.7 times the sweep's time (its
#: cost per rotation, turning, culling and splatting the cloud, stays); over the 144
#: turntable pairs 30-135 degrees apart, the 16 lose a right rotation on one pair at 45
#: and one at 60 degrees, which the other generators hold (the same poses).
SWEEP_PRESELECTED = 128
#: Largest angle (radians) between the two views' sensor directions the sweep tries (from
#: the normals: 62-86 degrees on dragon scans 48-72 degrees apart, 99-107 at 96 and
#: 123-127 at 120): views further apart share under a quarter of their hemispheres of
#: normals. At 110 degrees the sweep left out every dragon pair 120 degrees apart; at 135,
#: 2 more of the 14 pairs 96-120 degrees apart (two rotations each) succeed, the pairs
#: 24-72 degrees apart and the turntable pairs place the same poses, and the sweep places
#: 85% of its rotations instead of 67%.
SWEEP_SENSOR_ANGLE = np.deg2rad(135.0)


# -- search.climbs: the climbs -------------------------------------------------------------

#: Voxels added to the moving cloud's radius for the ball of a focused EGI, and the
#: distance (voxels) from a hypothesis' points of the scene's normals its climb matches.
FOCUS_MARGIN = 2.0


# -- search.confirmation: the early stop ---------------------------------------------------
# Calibrated on: instances 0-47 of each view suite and two rotations of each dragon pair
#   (the short polish's fit and closeness of the three best placed hypotheses, and whether
#   each was right); checked on instances 48-143 and four rotations
# Measured again by: python eval/bench_speed.py --suites SUITES --limit 6 --rotations 1
#   --repeats 3 (its early stops, and the wrong ones among them, per group)
# Trades: lower bars stop more calls early, faster, at the risk of a wrong early stop; the
#   rules were chosen for none, with headroom

#: Least fit of a confirmed pose. Wrong poses of occluded views fit up to 0.70 (a view
#: half hidden leaves a model turned a quarter or half a turn as much surface to match);
#: right ones of whole and partial views mostly over 0.8.
MIN_FIT = 0.75
#: Least lead in closeness of the best placed pose, polished, over the pose the search
#: returned for it to be returned instead (:func:`closer`): over the spread of the
#: closeness of one right pose polished two ways (95th percentile 0.03 on the view
#: suites). Occluded views 0-239: 6 poses won, none lost; full and partial views and the
#: dragon pairs, none either way.
CLOSER_MARGIN = 0.05
#: Placed hypotheses compared (the best and the distinct ones among the next).
CANDIDATES = 4
#: The cell (voxels) the fixed cloud is thinned to for the confirmation (one point per
#: half voxel, as users tuned for speed run Open3D's tutorial polish): its short
#: point-to-plane ICP of one point per voxel reads the surface through the fixed cloud's
#: normals, not their spacing, and so does the closeness; a raw scan (25-30 points per
#: voxel) cost 6-7 times as much for the same planes (the confirm stage halved over the
#: bench's groups, the same successes or one more). The final polish keeps every point: on
#: the suites' views and crops of a scene, whose truth is exact, thinning either cloud
#: there cost 0.1-0.7 degree of median error.
FIXED_CELL = 0.5


# -- search.dense: the dense search --------------------------------------------------------
# Calibrated on: the dragon scans 96-168 degrees apart, 4608 rotations
# Measured again by: python eval/bench_dense.py --suites SUITES --limit 24 --rotations 2
#   --all-cores
# Trades: a finer coarse grid, more rotations ranked again or climbed find the truth on
#   scans farther apart, for time

#: Cells the moving cloud spans at most on the grid that ranks every rotation first: on
#: the dragon scans (44-54 voxels across: 3 voxels) the truth's sample ranked 1-9 there
#: of about 3900.
COARSE_SPAN = 16.0
#: Rotations ranked again on the placement's grid.
RERANKED = 128
#: Best rotations there climbed by the compass search ...
REFINED = 4
#: ... each over this many samples' typical spacings from the ones before it: neighbours
#: of one sample climb to one peak. On the dragon scans 0 and 120 degrees apart the four
#: best samples, two of them 10 degrees from the first, all climbed to peaks 10-22 degrees
#: from the truth; the four best 1.5 spacings apart held one 13.5 degrees off that climbed
#: to 3.
START_SEPARATION = 1.5
#: Smallest turn of the compass search, radians: the polish takes on from there.
FINEST_STEP = np.deg2rad(0.75)
#: The typical distance (radians) from a rotation to the nearest of 1000 of
#: :func:`o3d_spectral.spectra.so3.uniform_rotations` (its docstring: 12 degrees at the
#: median); for ``n`` of them, this times ``(1000 / n)^(1/3)``.
SPACING_1000 = np.deg2rad(12.0)


# -- search.placement: placing the candidates ----------------------------------------------
# Calibrated on: the dragon scans, the servo's tabletop captures and 1.6 m RGB-D frames
# Measured again by: python eval/bench_pyramid.py --suites SUITES
# Trades: a finer grid places candidates at the voxel, for time on large clouds

#: Between two scans, candidates are placed on a grid where the moving cloud spans at most
#: this many cells: the voxel itself for the dragon scans (44-54 voxels across) and the
#: servo's tabletop captures (74-80); two 1.6 m RGB-D frames at 1 cm placed each of their
#: 48 candidates in 0.27 s at the voxel, in a tenth of that on 2.5-voxel cells.
PLACEMENT_SPAN = 96.0


# -- search.turns: the turns of a doubtful pose --------------------------------------------

#: The least-supported motion is taken as a turn when its rotation (scaled by the
#: points' RMS radius) is at least this share of the rotation and the slide along its
#: axis together: a mug's body turned about its axis is 0.96-0.99 rotation, a slide along
#: a plane or a cylinder's axis nearly none.
MIN_ROTATION_SHARE = 0.9
#: Turns are tried only where the inliers carry at most this share of the constraint on
#: the turn: at a mug's wrong turn, 0.05-0.2 of it (the handle's); on right poses of
#: objects without a symmetry, about the fit.
MAX_SUPPORT = 0.3
#: The turns that fit best after the brief polish, distinct from the pose and from one
#: another, that are polished and measured whole.
TURN_FINISHES = 2
