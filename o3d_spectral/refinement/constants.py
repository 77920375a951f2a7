"""Numeric constants of the polish (``o3d_spectral.refinement``), by the module using them."""

# -- refinement.icp: the polish ------------------------------------------------------------
# Calibrated on: the dragon scans 96 degrees apart and the suites' views
# Measured again by: python eval/bench_real.py --out RUN --rotations 5 --workers 1
# Trades: a longer reach or more cuts take a start farther off into the polish, for ICP runs

#: The polished pose is rejected when it keeps at most this share of the unpolished
#: pose's inliers (it slid off the surface).
GUARD_SHARE = 0.5

#: The tutorial's correspondence distance, voxels.
TUTORIAL_DISTANCE = 0.4

#: :func:`polish_within_reach`: the source's points farther from the target than the
#: ICP's correspondence distance and this many times it again are left out of the final
#: polish. The polish starts from a pose polished on the down-sampled source already and
#: moves the source by a fraction of the correspondence distance; a pose that moved some
#: point by as much is polished again on the whole source.
REACH = 1.5

#: :func:`polish_within_reach`: at most this many cuts of the source, each about the pose
#: the previous cut's ICP reached, before the ICP runs on the whole source. A polish from
#: a start a few degrees off (two scans 96 degrees apart, the sparse polish 3 degrees
#: short) settles on the second cut; each cut costs a fifth of the whole scan's ICP.
RECUTS = 3


# -- run: the polish's view of the target --------------------------------------------------

#: The refinement sees the target within the source's radius, or this many voxels if
#: more, of the ball holding the posed source.
REFINEMENT_MARGIN = 10.0
