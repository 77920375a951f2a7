"""The paper's control law on voxel grids: the clouds as the method reads them
(:mod:`.prepared`, :mod:`.prepared_target`, :mod:`.centring`), one evaluation of the
spectral corrections at a pose (:mod:`.stepper`, :mod:`.evaluation`) and the law's loop
(:mod:`.loop`)."""
