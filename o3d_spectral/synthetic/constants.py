"""Numeric constants of the synthetic data, by the module using them."""

# -- synthetic.instance: instances ---------------------------------------------------------

#: Random draws a placement (camera, occluder, object on the table) makes before giving up.
MAX_TRIES = 200

#: Label of table and occluder points in ``Instance.target_labels``.
BACKGROUND = -1


# -- synthetic.manifest: suite manifests ---------------------------------------------------

#: Largest translation coordinate a pose may have, in its file's units (metres or mm).
MAX_TRANSLATION = 1e6


# -- synthetic.suite: suites on disk -------------------------------------------------------

#: The version of a suite manifest's format (``synthetic.suite.FORMAT``), raised when a
#: field changes meaning.
VERSION = 1


# -- synthetic.symmetry: the models' symmetries --------------------------------------------

#: Correspondence distance (m) of the ICP that refines each symmetry axis on the mesh.
REFINE_DISTANCE = 0.01


# -- synthetic.turntable: the turntable pairs ----------------------------------------------

#: Turntable angles (degrees) between the two views that the benchmarks use.
TURNTABLE_ANGLES = (30, 45, 60, 90, 120, 135)
#: Camera elevations (degrees above the turntable's plane) that the benchmarks use.
TURNTABLE_ELEVATIONS = (20, 45)
#: Camera distance from the model's centre, metres (a depth camera's working distance for
#: objects 5-25 cm across).
DISTANCE = 0.45
#: Fewest points of a view: a view that shows less (a thin object edge-on) is drawn again.
TURNTABLE_MIN_POINTS = 500
#: Draws of the azimuth before giving up on a pair.
TURNTABLE_TRIES = 20


# -- synthetic.wide: the wide tabletop -----------------------------------------------------

#: Objects per square metre of table (the cluttered suite's tabletops hold 3-8 on 0.48 m²).
OBJECTS_PER_M2 = 8.0
#: Spacing of the reconstruction's points, metres.
SPACING = 0.004
#: Standard deviation of the reconstruction's noise, metres.
NOISE = 0.001
#: Fewest points of the object's view.
MIN_VIEW_POINTS = 500
