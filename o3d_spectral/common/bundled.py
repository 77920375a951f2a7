"""Where the bundled data lives: package data under ``o3d_spectral/datasets``, read through
:mod:`importlib.resources`, or a folder that an environment variable names instead.

Installed as files (a wheel in any ``site-packages``, ``--user``, ``--target``, an editable
install or the checkout itself) the data is read where it lies. From a zip import it is
extracted once per process into a temporary folder, removed at exit, since Open3D reads
meshes and clouds only from file-system paths.
"""

from __future__ import annotations

import atexit
import contextlib
import os
import tempfile
from collections.abc import Callable
from functools import cache
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from importlib.resources.abc import Traversable

__all__ = ["bundled_folder", "data_folder"]

#: The package-data folder holding the bundled data, relative to ``o3d_spectral``.
DATA = "datasets"

_extracted = contextlib.ExitStack()
atexit.register(_extracted.close)


def _copy_tree(source: Traversable, destination: Path) -> None:
    """Copy the resource folder ``source`` into the new folder ``destination``."""
    destination.mkdir()
    for entry in source.iterdir():
        if entry.is_dir():
            _copy_tree(entry, destination / entry.name)
        else:
            (destination / entry.name).write_bytes(entry.read_bytes())


@cache
def data_folder(name: str) -> Path | None:
    """The bundled folder ``o3d_spectral/datasets/<name>`` as a file-system path, None if
    the installation has no such folder.

    Parameters
    ----------
    name : str
        Sub-folder of the bundled data, e.g. ``"objects"`` or ``"real"``.

    Returns
    -------
    pathlib.Path or None
        The folder itself when the package is installed as files, else a copy extracted
        once per process.
    """
    folder = resources.files("o3d_spectral") / DATA / name
    if not folder.is_dir():
        return None
    if isinstance(folder, Path):
        return folder
    copy = Path(_extracted.enter_context(tempfile.TemporaryDirectory(prefix="o3d-spectral-")))
    _copy_tree(folder, copy / name)
    return copy / name


def bundled_folder(name: str, env: str, holds: Callable[[Path], bool], what: str) -> Path:
    """The first of ``$env`` and the bundled ``o3d_spectral/datasets/<name>`` for which
    ``holds`` is true.

    Parameters
    ----------
    name : str
        Sub-folder of the bundled data.
    env : str
        Environment variable that names another folder, looked in first.
    holds : callable
        True for a folder that holds the data wanted.
    what : str
        The data's name in the error message.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    FileNotFoundError
        Naming every folder looked in and the variable that points elsewhere.
    """
    candidates = []
    if folder := os.environ.get(env):
        candidates.append(Path(folder))
    if (bundled := data_folder(name)) is not None:
        candidates.append(bundled)
    for folder in candidates:
        if holds(folder):
            return folder
    looked = ", ".join(str(c) for c in candidates) or f"the package data ({DATA}/{name})"
    raise FileNotFoundError(
        f"no bundled {what} found; looked in {looked}. "
        f"Set {env} to a folder laid out as o3d_spectral/{DATA}/{name}."
    )
