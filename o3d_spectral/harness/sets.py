"""The sets of instances ``eval`` runs: scene suites, a BOP dataset's objects (crops and
whole frames, :mod:`~o3d_spectral.harness.bop`) and 3DMatch-layout scan pairs
(:mod:`~o3d_spectral.harness.pairs`).

Each set has a ``spec``, a tuple of plain values that opens it again in a worker process
(:func:`open_set`), and a name (its folder's, or the dataset's with split and kind).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from pathlib import Path

from o3d_spectral.harness.bop import KINDS, BopSet
from o3d_spectral.harness.pairs import PairSet, pair_scenes
from o3d_spectral.synthetic.suite import Suite, load_suite

__all__ = ["bop_sets", "open_set", "pair_sets", "set_spec"]


@functools.cache
def open_set(spec: tuple) -> Suite | BopSet | PairSet:
    """The instance set ``spec`` names, opened once per process: ``("suite", folder)``,
    ``("bop", folder, split, kind, scenes, objects)`` or ``("pairs", folder)``."""
    kind, folder, *rest = spec
    if kind == "bop":
        split, which, scenes, objects = rest
        return BopSet(folder, split, which, scenes=scenes, objects=objects)
    if kind == "pairs":
        return PairSet(folder)
    return load_suite(folder)


def set_spec(instances: Suite | BopSet | PairSet) -> tuple:
    """The ``spec`` that opens ``instances`` again (:func:`open_set`)."""
    return getattr(instances, "spec", None) or ("suite", str(instances.root))


def bop_sets(
    root: str | Path,
    split: str = "test",
    *,
    scenes: Sequence[int] | None = None,
    objects: Sequence[int] | None = None,
) -> list[BopSet]:
    """A BOP dataset's two sets of instances: the objects against their visible-mask
    crops, and against the whole depth frames (:class:`~o3d_spectral.harness.bop.BopSet`)."""
    return [
        BopSet(root, split, kind, scenes=None if scenes is None else tuple(scenes),
               objects=None if objects is None else tuple(objects))
        for kind in KINDS
    ]


def pair_sets(root: str | Path) -> list[PairSet]:
    """One set per 3DMatch-layout scene folder of ``root`` (``root`` itself, or its
    sub-folders holding ``cloud_bin_*.ply``)."""
    return [PairSet(scene) for scene in pair_scenes(root)]
