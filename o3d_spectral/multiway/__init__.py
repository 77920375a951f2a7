"""Many clouds of one object or scene, in any frames, registered into one model: the
options (:mod:`.options`), the pose graph (:mod:`.graph`) and the call
(:mod:`.registration`)."""
