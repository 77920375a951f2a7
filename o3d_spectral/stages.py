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

__all__ = ["StageClock"]

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
        """Time the block as stage ``name`` and log it at INFO when it ends."""
        start = time.perf_counter()
        try:
            yield
        finally:
            seconds = time.perf_counter() - start
            self.times[name] = self.times.get(name, 0.0) + seconds
            logger.info("%s: %.3f s", name, seconds)
