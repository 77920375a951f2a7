"""The voxel size: read off two clouds' spacing and extent (:mod:`.suggestion`), or chosen
by registering at a few sizes (:mod:`.by_trial`)."""
