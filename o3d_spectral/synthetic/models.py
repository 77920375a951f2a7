"""Bundled object models (YCB, CC BY 4.0; see ``datasets/README.md``).

The twelve meshes live in the repository's ``datasets/objects`` folder and are installed
to ``<prefix>/share/o3d-spectral/objects`` by ``pip install``. Set the environment
variable ``O3D_SPECTRAL_DATA`` to a folder of ``*.ply`` meshes to use another one.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import open3d as o3d

__all__ = ["objects_dir", "model_names", "model_path", "load_model"]


def objects_dir() -> Path:
    """Folder holding the bundled object meshes.

    Raises
    ------
    FileNotFoundError
        If no candidate folder holds ``*.ply`` files.
    """
    candidates = []
    if env := os.environ.get("O3D_SPECTRAL_DATA"):
        candidates.append(Path(env))
    candidates.append(Path(__file__).resolve().parents[2] / "datasets" / "objects")
    candidates.append(Path(sys.prefix) / "share" / "o3d-spectral" / "objects")
    for folder in candidates:
        if folder.is_dir() and any(folder.glob("*.ply")):
            return folder
    raise FileNotFoundError(
        "no bundled object models found; looked in "
        + ", ".join(str(c) for c in candidates)
        + ". Set O3D_SPECTRAL_DATA to a folder of .ply meshes."
    )


def model_names() -> list[str]:
    """Names of the bundled models (file stems), sorted."""
    return sorted(p.stem for p in objects_dir().glob("*.ply"))


def model_path(name: str) -> Path:
    """Path of the bundled mesh ``name`` (e.g. ``"mustard_bottle"``)."""
    path = objects_dir() / f"{name}.ply"
    if not path.is_file():
        raise ValueError(f"unknown model {name!r}; available: {', '.join(model_names())}")
    return path


def load_model(name: str) -> o3d.geometry.TriangleMesh:
    """Load the bundled mesh ``name`` (metres) with vertex and triangle normals."""
    mesh = o3d.io.read_triangle_mesh(str(model_path(name)))
    mesh.compute_triangle_normals()
    if not mesh.has_vertex_normals():
        mesh.compute_vertex_normals()
    return mesh
