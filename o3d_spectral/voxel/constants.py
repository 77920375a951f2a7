"""Numeric constants of the voxel size (``o3d_spectral.voxel``), by the module using them."""

# -- voxel.by_trial: the voxel by trial ----------------------------------------------------
# Calibrated on: the dragon scans 96-120 degrees apart and the YCB-Video crops
# Measured again by: python eval/voxel_advice.py --suites SUITES --out RUN --trial
# Trades: each size tried costs a registration

#: Factors of :func:`~o3d_spectral.suggest_voxel_size`'s size tried, in this order: the
#: rule's size, a coarser one (a median 0.6 of the rule's time; a YCB-Video crop
#: lost at 3.6 mm was right at 5-8 mm), a finer one (dragon scans 96-120 degrees apart
#: lost at the rule's 6.3-7.2 mm were right at 5 mm). ``eval/voxel_advice.py --trial``
#: measures it (docs/conventions.md).
VOXEL_LADDER = (1.0, 1.4, 0.75)


# -- voxel.suggestion: the suggested voxel -------------------------------------------------
# Calibrated on: the synthetic suites, the dragon scans and the YCB-Video frame
# Measured again by: python eval/voxel_advice.py --suites SUITES --out RUN
# Trades: a coarser voxel is faster and tolerates sparse clouds; a finer one tells more
#   detail, until a view or a scene spans too many voxels

#: Chosen on the synthetic suites (models of 3000 points: 2.4-6.3 mm spacing) and the
#: real scans (``eval/voxel_advice.py``, docs/results.md):
#:
#: The voxel is at least this many times the sparser cloud's point spacing. Models of
#: 3000 points on a 35 cm box (6.3 mm spacing) registered at 6-11 mm, not at 15.7 mm
#: (2.5 spacings) in a scene or an occluded view: a few spacings are not needed, one is.
SPACINGS = 1.0
#: The voxel is at least the smaller cloud's diameter over this: the suites' objects
#: (15-35 cm) at 8 mm span 18-44 voxels, and registered as well at 6 mm, better in
#: occluded views; the dragon scans (23-26 cm) registered alike from 3.5 to 10 mm when
#: 24-72 degrees apart.
VOXELS_ACROSS = 36.0
#: The voxel is at least the larger cloud's diameter over this: a whole RGB-D frame
#: (1.4 m) registered its objects at 8 mm (175 voxels across) and lost them at 4-7 mm
#: (crops of the same objects registered at 5.2-12 mm).
MAX_VOXELS_ACROSS = 175.0
#: Neighbours the spacing is measured over (the k-th neighbour's distance ``r_k`` holds
#: ``k`` points in a disc of area ``pi r_k^2``: a spacing of ``r_k sqrt(pi / k)``).
NEIGHBOURS = 8
#: Points whose neighbours are measured at most (evenly spread over the cloud).
SAMPLES = 4096
#: Points a cloud's spacing is measured among at most (a random subset beyond).
MAX_TREE_POINTS = 50_000
