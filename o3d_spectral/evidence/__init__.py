"""What the data say about a pose: its fit after a short polish (:mod:`.fit`), when two
poses are distinct (:mod:`.poses`), the motions its inliers leave free
(:mod:`.free_motions`), the evidence's numbers (:mod:`.pose`), the verification against
rival poses (:mod:`.verification`), the calibrated confidence (:mod:`.confidence`), the
warnings and notes (:mod:`.diagnostics`) and the verdict that gathers them
(:mod:`.verdict`)."""
