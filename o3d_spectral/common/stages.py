"""The stage record of a registration call: each stage's time, logged as it ends.

Every stage of :func:`o3d_spectral.registration_spectral` and
:func:`o3d_spectral.registration_spectral_global` runs inside :meth:`StageClock.stage`;
its wall-clock seconds go to ``result.stage_times`` (in the order the stages ran) and to
the ``o3d_spectral`` logger at INFO, so a long call shows its progress
(``logging.basicConfig(level=logging.INFO)``, or ``o3d-spectral -v register``).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["StageClock", "GLOBAL_STAGES", "LOCAL_STAGES"]

#: The stages of :func:`o3d_spectral.registration_spectral_global`, in the order they can
#: run (a call runs a subset: ``confirm`` not in a scene, ``sweep`` and ``ascent`` between
#: two scans only, ``climbs`` where nothing was confirmed, ``turns`` where the pose may be
#: wrong, ``second_opinions`` where the climbed pose still may be, ``dense_sweep`` where
#: it still may be on the CPU, after which the stages from ``confirm`` on can run again and
#: add up).
GLOBAL_STAGES = ("prepare", "candidates", "confirm", "sweep", "climbs", "ascent", "polish",
                 "turns", "second_opinions", "dense_sweep")
#: The stages of :func:`o3d_spectral.registration_spectral`.
LOCAL_STAGES = ("prepare", "law", "polish")

logger = logging.getLogger("o3d_spectral")


class StageClock:
    """Times named stages of one call.

    Attributes
    ----------
    times : dict of str to float
        Seconds spent in each stage, in the order they ran (a stage run twice adds up).
    """

    def __init__(self) -> None:
        self.times: dict[str, float] = {}

    @contextmanager
    def stage(self, name: str) -> Iterator[None]:
        """Time the block as stage ``name`` (one of :data:`GLOBAL_STAGES` or
        :data:`LOCAL_STAGES`) and log it at INFO when it ends."""
        if name not in GLOBAL_STAGES + LOCAL_STAGES:
            raise ValueError(f"unknown stage {name!r}")
        start = time.perf_counter()
        try:
            yield
        finally:
            seconds = time.perf_counter() - start
            self.times[name] = self.times.get(name, 0.0) + seconds
            logger.info("%s: %.3f s", name, seconds)
