"""The installed distribution's version, read from its metadata so that it cannot drift
from ``pyproject.toml``; ``0+unknown`` for a bare source tree on ``sys.path``."""

from importlib import metadata

try:
    __version__ = metadata.version("o3d-spectral")
except metadata.PackageNotFoundError:
    __version__ = "0+unknown"
