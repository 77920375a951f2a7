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

#: :func:`refine`: the final ICP reads at most this many of the source's points, evenly
#: spread over its order: each of its iterations costs in proportion to the points while
#: its pose stops gaining long before. Room fragments of 90-220k points at 5 cm (the
#: room of ``eval/bench_speed.py --groups room_fragments --repeats 3`` at commit fd6c282,
#: before the room held clutter on its floor; 14 pairs, one thread):
#: the 13 right pairs' median errors 0.057 degree and 1.25 mm on every point, 0.049 /
#: 1.16 at this budget; the calls' total time 58.4 -> 49.6 s, most of it where the
#: polish of a wrong turn slid over 200k points (12.1 -> 5.3 s), the median unchanged
#: (3.0 s). At 25,000 two pairs turn into the room's half-turn twin, at 50,000 none. No
#: object cloud of the benches holds as many (the largest 63k).
MAX_POLISH_POINTS = 100_000

#: :func:`polish_within_reach`: at most this many cuts of the source, each about the pose
#: the previous cut's ICP reached, before the ICP runs on the whole source. A polish from
#: a start a few degrees off (two scans 96 degrees apart, the sparse polish 3 degrees
#: short) settles on the second cut; each cut costs a fifth of the whole scan's ICP.
RECUTS = 3


# -- run: the polish's view of the target --------------------------------------------------

#: The refinement sees the target within the source's radius, or this many voxels if
#: more, of the ball holding the posed source.
REFINEMENT_MARGIN = 10.0
