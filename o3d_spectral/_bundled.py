"""Where the bundled data lives: the repository's ``datasets/`` or the installed copy."""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from pathlib import Path


def bundled_folder(name: str, env: str, holds: Callable[[Path], bool], what: str) -> Path:
    """The first of ``$env``, ``datasets/<name>`` in a source checkout and
    ``<prefix>/share/o3d-spectral/<name>`` in an installation for which ``holds`` is true.

    Raises
    ------
    FileNotFoundError
        Naming every folder looked in and the variable that points elsewhere.
    """
    candidates = []
    if folder := os.environ.get(env):
        candidates.append(Path(folder))
    candidates.append(Path(__file__).resolve().parents[1] / "datasets" / name)
    candidates.append(Path(sys.prefix) / "share" / "o3d-spectral" / name)
    for folder in candidates:
        if holds(folder):
            return folder
    raise FileNotFoundError(
        f"no bundled {what} found; looked in " + ", ".join(str(c) for c in candidates)
        + f". Set {env} to a folder laid out as datasets/{name}."
    )
