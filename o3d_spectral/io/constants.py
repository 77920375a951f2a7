"""Numeric constants of the reading of clouds (``o3d_spectral.io``), by the module using them."""

# -- io.cloud: input clouds ----------------------------------------------------------------

#: Fewest points, and fewest occupied voxels after down-sampling, the method accepts.
MIN_POINTS = 10
#: :func:`dense_bounds`: points beyond a gap of this many voxels along an axis, holding at
#: most ``ISOLATED_SHARE`` of the cloud, are isolated (flying pixels, stray returns).
ISOLATED_GAP = 10.0
ISOLATED_SHARE = 0.01


# -- io.density: dense clouds --------------------------------------------------------------
# Calibrated on: depth views thinned and densified 1-16x at a fixed voxel
# Measured again by: python eval/bench_density.py --out RUN
# Trades: a lower density bar thins more clouds, faster, at the cost of their surface's
#   resolution

#: The cell (voxels) a dense cloud keeps one point of: the resolution at which the method
#: reads a surface.
CELL = 0.25
#: A cloud averaging over this many points per occupied cell is dense: a surface crosses
#: about 1 / CELL^2 = 16 of a voxel's cells, so 64 points per occupied voxel. At 4x and
#: 16x the points of a depth view (110 and 450 per voxel) the call then costs what it
#: costs at 1x (28 per voxel), where the poses are as accurate (``eval/bench_density.py``).
DENSE_PER_CELL = 4.0
#: Cells a side beyond which a cloud is not looked at (a voxel size far too small for
#: the cloud, which the grids' memory check then refuses by name).
MAX_CELLS = 2.0**31


# -- io.normals: normals and single views --------------------------------------------------

#: Normals are oriented along the surface over at most this many points (:func:`orient`).
PROPAGATED_POINTS = 5000
#: Largest move (share of the extent) of exactly cospherical points, which Qhull cannot
#: triangulate, before their orientation is propagated (:func:`_propagated`).
JOGGLE = 1e-6
#: :func:`view_direction`: a single view when at least this share of its normals lie in
#: the hemisphere about their mean, and the mean's length is at least ``VIEW_MEAN``.
VIEW_SHARE = 0.9
VIEW_MEAN = 0.4
#: :func:`sensor_position` puts the distant sensor of a view recognised from its normals
#: this many times the cloud's size (at least 1 m) away.
DISTANT_SENSOR = 1000.0
#: :func:`is_depth_map_along`: depth gap (voxels) and share of rays allowed to exceed it.
ALONG_GAP, ALONG_SHARE = 1.5, 0.05
#: :func:`is_depth_map`: rays binned this many voxels wide (at the median depth); a depth
#: map when under DEPTH_SHARE of the bins hold depths over DEPTH_GAP voxels apart.
DEPTH_BIN, DEPTH_GAP, DEPTH_SHARE = 0.5, 3.0, 0.1
#: :func:`sensor_direction`: candidates within AROUND_ANGLE (deg) of ``around``, ties within
#: SPREAD_TIE of the fewest second surfaces; :func:`orient`: OFF_AXIS_ANGLE (deg) off-axis.
AROUND_ANGLE, SPREAD_TIE, OFF_AXIS_ANGLE = 60.0, 0.005, 45.0


# -- io.signs: normals' signs --------------------------------------------------------------
# Calibrated on: the suites' normals (from orientable meshes) and Open3D's unoriented
#   estimate on the bundled real scans
# Measured again by: python eval/bench_real.py --out RUN --modes oriented unoriented
# Trades: a lower bar re-orients more given normals; a higher one keeps an unoriented
#   estimate

#: Given normals whose neighbours disagree in sign more often than this are re-oriented
#: (the suites' normals from orientable meshes: at most 4.4%; Open3D's unoriented
#: estimate on the bundled real scans: 5.6-23%, median 7.8%).
SIGN_DISAGREEMENT = 0.05
#: Of given normals over :data:`SIGN_DISAGREEMENT`, those with at least this share of
#: the disagreeing pairs back to back (:func:`back_to_back`) are the faces of walls
#: thinner than their spacing (the suites' bowl 97% and mug 96%: walls 0.8 and 1.5 mm);
#: Open3D's unoriented estimate: 6-48% (the bundled models and real scans).
THIN_WALLS = 0.8


# -- io.units: the clouds' units -----------------------------------------------------------

#: Extents (diagonals, :func:`span`) differing by this factor or more are refused.
MAX_EXTENT_RATIO = 50.0

#: :func:`span` leaves out this share of the points at each end of each axis (flying
#: pixels, stray returns).
OUTLYING_SHARE = 0.01
#: :func:`span` measures at most about this many points (0.02 s), evenly spread.
SPAN_POINTS = 100_000
