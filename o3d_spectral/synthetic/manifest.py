"""Checks of a suite's ``manifest.json`` and of the instance files it names.

A manifest comes from disk and may have been edited, cut off or crafted: every key a
suite uses is checked once, when the suite is opened, and an error is a ``ValueError``
naming the file and the key (``instances[3].T_gt``). Instance files must be plain names
inside the suite folder: absolute paths, ``..`` and links leading out of it are refused.
"""

from __future__ import annotations

import json
import numbers
from pathlib import Path

import numpy as np

from o3d_spectral.io.files import atomic_write_text
from o3d_spectral.synthetic.constants import MAX_TRANSLATION
from o3d_spectral.synthetic.instance import CONDITIONS

__all__ = ["MAX_TRANSLATION", "atomic_write_text", "check_manifest", "check_pose", "instance_path",
           "read_manifest"]

#: Top-level keys and the JSON types they must have.
_TOP = {"format": str, "version": int, "condition": str, "n": int, "seed": int,
        "options": dict, "instances": list}
#: Keys of each instance entry and their JSON types (``T_gt`` and the like: 4x4 lists).
_ENTRY = {"index": int, "source": str, "target": str, "T_gt": list, "source_from_model": list}


def _kind(value: object, expected: type) -> bool:
    if expected is int:
        return isinstance(value, numbers.Integral) and not isinstance(value, bool)
    return isinstance(value, expected)


def check_pose(where: object, key: str, value: object, *, atol: float = 1e-6) -> np.ndarray:
    """``value`` as a 4x4 rigid transformation (a rotation, a finite translation under
    :data:`MAX_TRANSLATION`, a last row ``0 0 0 1``), else ``ValueError`` naming ``where``
    (a file, an entry) and ``key``."""
    try:
        matrix = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{where}: {key} must be a 4x4 matrix of numbers") from None
    if matrix.shape != (4, 4) or not np.all(np.isfinite(matrix)):
        raise ValueError(f"{where}: {key} must be a finite 4x4 matrix, got shape {matrix.shape}"
                         + ("" if matrix.shape != (4, 4) else " with NaN or infinite values"))
    rotation = matrix[:3, :3]
    rigid = np.allclose(rotation @ rotation.T, np.eye(3), atol=atol) and np.allclose(
        matrix[3], [0.0, 0.0, 0.0, 1.0])
    if not (rigid and np.linalg.det(rotation) > 0):
        raise ValueError(f"{where}: {key} must be a rigid transformation (a rotation, not "
                         "scaled nor a reflection, and a last row 0 0 0 1)")
    if np.max(np.abs(matrix[:3, 3])) > MAX_TRANSLATION:
        raise ValueError(f"{where}: {key} has a translation over {MAX_TRANSLATION:g}")
    return matrix


def _check_name(path: Path, key: str, name: str) -> None:
    """An instance file's name: relative, without ``..``, inside the suite folder."""
    if not name or Path(name).is_absolute() or ".." in Path(name).parts or "\\" in name:
        raise ValueError(
            f"{path}: {key} must name a file inside the suite folder, got {name!r}"
        )


def check_manifest(manifest: object, path: Path) -> dict:
    """``manifest`` (parsed from ``path``) if it has every key a suite uses with the right
    type; ``ValueError`` naming ``path`` and the first bad key otherwise."""
    if not isinstance(manifest, dict):
        raise ValueError(f"{path}: a manifest must be a JSON object, got {type(manifest).__name__}")
    for key, expected in _TOP.items():
        if key not in manifest:
            raise ValueError(f"{path}: the manifest has no {key!r}")
        if not _kind(manifest[key], expected):
            raise ValueError(
                f"{path}: {key} must be a JSON {expected.__name__}, got {manifest[key]!r}"[:300]
            )
    if manifest["condition"] not in CONDITIONS:
        raise ValueError(f"{path}: condition must be one of {CONDITIONS}, "
                         f"got {manifest['condition']!r}")
    if manifest["seed"] < 0:
        raise ValueError(f"{path}: seed must be >= 0, got {manifest['seed']}")
    for k, entry in enumerate(manifest["instances"]):
        where = f"instances[{k}]"
        if not isinstance(entry, dict):
            raise ValueError(f"{path}: {where} must be a JSON object")
        for key, expected in _ENTRY.items():
            if key not in entry:
                raise ValueError(f"{path}: {where} has no {key!r}")
            if not _kind(entry[key], expected):
                raise ValueError(f"{path}: {where}.{key} must be a JSON {expected.__name__}, "
                                 f"got {entry[key]!r}"[:300])
        for key in ("source", "target"):
            _check_name(path, f"{where}.{key}", entry[key])
        for key in ("T_gt", "source_from_model"):
            check_pose(path, f"{where}.{key}", entry[key])
        if not isinstance(entry.get("condition", manifest["condition"]), str):
            raise ValueError(f"{path}: {where}.condition must be a JSON str")
    return manifest


def read_manifest(path: Path) -> dict:
    """The checked manifest in ``path`` (see :func:`check_manifest`)."""
    try:
        manifest = json.loads(path.read_text())
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise ValueError(f"{path}: not a JSON manifest ({error})") from None
    return check_manifest(manifest, path)


def instance_path(root: Path, name: str) -> Path:
    """The instance file ``name`` in the suite folder ``root``; ``ValueError`` when it
    leads out of it (through a link), ``FileNotFoundError`` when it is missing."""
    _check_name(root, "instance file", name)
    path = root / name
    if not path.resolve().is_relative_to(root.resolve()):
        raise ValueError(f"{path}: an instance file must be inside the suite folder {root}")
    if not path.is_file():
        raise FileNotFoundError(f"missing instance file {path}; make the suite again")
    return path
