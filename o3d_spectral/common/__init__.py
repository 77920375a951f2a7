"""What every layer of the package uses: input checks (:mod:`.checks`), optional
libraries loaded on first use (:mod:`.extras`, :mod:`.lazy`), the bundled data
(:mod:`.bundled`), work on threads (:mod:`.parallel`), a call's stages and their clock
(:mod:`.stages`) and the errors between two poses (:mod:`.pose_errors`)."""
