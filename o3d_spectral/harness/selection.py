"""Which instances of a suite a session runs: the first N (``--limit``), a seeded sample
(``--sample``), one shard of several (``--shard i/n``), and the tuning split.

Every choice depends only on the suite (its condition and seed), the instance index and
the run seed, never on the order of the suites or on which machine asks, so ``n`` machines
running shards ``0/n`` .. ``n-1/n`` into one run folder run each instance exactly once.
"""

from __future__ import annotations

import hashlib
import zlib

import numpy as np

from .constants import TUNING_MODULUS

__all__ = [
    "TUNING_MODULUS",
    "TUNING_SPLIT",
    "in_shard",
    "in_tuning_split",
    "parse_shard",
    "selected_indices",
]

TUNING_SPLIT = f"index % {TUNING_MODULUS} == 0"


def in_tuning_split(index: int) -> bool:
    """Whether instance ``index`` of a suite is in the tuning split (:data:`TUNING_SPLIT`)."""
    return index % TUNING_MODULUS == 0


def parse_shard(text: str) -> tuple[int, int]:
    """``"i/n"`` as ``(i, n)`` with ``0 <= i < n``; ``ValueError`` otherwise."""
    try:
        index, count = (int(part) for part in text.split("/"))
    except ValueError:
        raise ValueError(f"shard must be I/N (e.g. 0/4), got {text!r}") from None
    if not 0 <= index < count:
        raise ValueError(f"shard I/N needs 0 <= I < N, got {text!r}")
    return index, count


def in_shard(condition: str, suite_seed: int, index: int, shard: tuple[int, int]) -> bool:
    """Whether the instance belongs to ``shard`` ``(i, n)``: a SHA-256 of its key
    (condition, suite seed, index), as an integer, modulo ``n`` is ``i``. (A CRC-32 put
    instances 0-3 of a suite in one shard of two and 4-7 in the other: its low bits follow
    a few bits of the last digit.)"""
    digest = hashlib.sha256(f"{condition}/{suite_seed}/{index}".encode()).digest()
    return int.from_bytes(digest[:8], "little") % shard[1] == shard[0]


def selected_indices(
    size: int,
    *,
    condition: str,
    suite_seed: int,
    limit: int | None = None,
    sample: int | None = None,
    seed: int = 0,
    shard: tuple[int, int] | None = None,
) -> list[int]:
    """Indices of a suite of ``size`` instances that a session runs, ascending.

    ``limit``: the first ``limit``; ``sample``: ``sample`` drawn without replacement, seeded
    by the run ``seed`` and the suite (the same draw on every machine); at most one of the
    two. ``shard``: then only those in the shard (:func:`in_shard`), so the shards of a
    limited or sampled run split that run.
    """
    if limit is not None and sample is not None:
        raise ValueError("give limit or sample, not both")
    indices = list(range(size if limit is None else min(limit, size)))
    if sample is not None and sample < size:
        words = [seed, suite_seed, zlib.crc32(condition.encode())]
        rng = np.random.default_rng(np.random.SeedSequence(words))
        indices = sorted(int(i) for i in rng.choice(size, size=sample, replace=False))
    if shard is not None:
        indices = [i for i in indices if in_shard(condition, suite_seed, i, shard)]
    return indices
