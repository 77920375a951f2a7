"""Numeric constants of multiway registration, by the module using them."""

# -- multiway.graph: the pose graph --------------------------------------------------------

#: The refinement's second ICP: on the clouds down-sampled to this many voxels, with
#: correspondences up to :data:`FINE_DISTANCE` voxels (the registration's own polish).
FINE_CELL, FINE_DISTANCE = 0.25, 0.4
#: Radius (voxels) of the normals of the voxel down-samples.
NORMAL_VOXELS = 2.5
