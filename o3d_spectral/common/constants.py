"""Numeric constants of what every layer uses, by the module using them."""

# -- common.checks: validation -------------------------------------------------------------

#: :func:`check_transformation`: a rotation block ``R`` with ``max |R^T R - I|`` up to this
#: (a pose written with 5 decimals is about 1e-5 off) is re-orthonormalised; beyond it the
#: matrix is refused.
RIGID_TOLERANCE = 1e-4

#: Most voxels a cloud may span along an axis: a grid 2**20 voxels a side exceeds any
#: memory, and Open3D's down-sampling fails beyond 2**31 (a voxel_size of 1e-12 m).
MAX_VOXELS_ACROSS = 2**20
