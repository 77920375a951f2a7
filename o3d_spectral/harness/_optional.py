"""Optional packages: the ``harness`` extra (pandas, matplotlib, tqdm), imported on use with
an install hint, and orjson, used when it is installed."""

from __future__ import annotations

import contextlib
import json
from types import ModuleType

from o3d_spectral.common import extras

try:  # not a dependency: reads JSON in a third of the time of json
    from orjson import loads as _fast_loads
except ImportError:  # pragma: no cover - exercised when orjson is missing
    _fast_loads = json.loads


def require(module: str) -> ModuleType:
    """Import ``module`` or raise :class:`~o3d_spectral.common.extras.MissingExtraError` (an
    ``ImportError``) naming the extra to install."""
    return extras.require(module, "the evaluation harness")


def parse_json(text: str) -> object:
    """The JSON value of ``text``, None if it is not JSON: by orjson when it is installed,
    by json what orjson refuses and ``json.dumps`` writes (NaN, Infinity, integers beyond
    64 bits); both read a number to the same value."""
    for loads in (_fast_loads, json.loads):
        with contextlib.suppress(ValueError):  # both parsers' errors are ValueErrors
            return loads(text)
    return None
