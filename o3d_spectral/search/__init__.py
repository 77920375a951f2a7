"""The global search over all of SO(3), stage by stage.

- :mod:`~o3d_spectral.search.situation`: which kind of problem a call is, decided once;
- :mod:`~o3d_spectral.search.candidates`: rotation candidates (EGI peaks, the shells, the
  sweep);
- :mod:`~o3d_spectral.search.placement`: candidates placed by phase correlation
  (:class:`~o3d_spectral.search.placement.Hypothesis`);
- :mod:`~o3d_spectral.search.confirmation`: the early stop on a clearly right pose;
- :mod:`~o3d_spectral.search.climbs`: the law climbed from the best hypotheses;
- :mod:`~o3d_spectral.search.ascent`: the phase-correlation peak climbed over rotations;
- :mod:`~o3d_spectral.evidence.poses`: when two poses are distinct, the confidence;
- :mod:`~o3d_spectral.search.global_search`: :class:`GlobalSearch`, the stages as one
  object over their shared state.
"""

from .global_search import GlobalSearch, Ranking, SearchState
from .situation import Kind, Situation, situation

__all__ = ["GlobalSearch", "Ranking", "SearchState", "Kind", "Situation", "situation"]
