"""Numeric constants of multiway registration, by the module using them."""

# -- multiway.graph: the pose graph --------------------------------------------------------

#: The refinement's second ICP: on the clouds down-sampled to this many voxels, with
#: correspondences up to :data:`FINE_DISTANCE` voxels (the registration's own polish).
FINE_CELL, FINE_DISTANCE = 0.25, 0.4
#: Radius (voxels) of the normals of the voxel down-samples.
NORMAL_VOXELS = 2.5
#: A point lies in another scan's free space when it is nearer to that scan's camera than
#: the surface the camera saw in its direction by more than this many voxels: twice the
#: grid's own resolution, beyond the depth noise a voxel is chosen above and the pairwise
#: poses' error (a fraction of a voxel after the polish).
FREE_SPACE_MARGIN = 2.0
