"""The polish of a registration's final pose: Open3D's point-to-plane ICP with a guard
(:mod:`.icp`)."""
