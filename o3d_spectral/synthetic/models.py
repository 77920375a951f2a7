"""Bundled object models (YCB, CC BY 4.0; see ``o3d_spectral/datasets/README.md``).

The twelve meshes are package data, ``o3d_spectral/datasets/objects``, read through
:mod:`importlib.resources` wherever the package is installed. Set the environment
variable ``O3D_SPECTRAL_DATA`` to a folder of ``*.ply`` meshes to use another one.
"""

from __future__ import annotations

from pathlib import Path

import open3d as o3d

from o3d_spectral.common.bundled import bundled_folder

__all__ = ["objects_dir", "model_names", "model_path", "load_model"]


def objects_dir() -> Path:
    """Folder holding the bundled object meshes.

    Raises
    ------
    FileNotFoundError
        If no candidate folder holds ``*.ply`` files.
    """
    return bundled_folder("objects", "O3D_SPECTRAL_DATA",
                          lambda folder: folder.is_dir() and any(folder.glob("*.ply")),
                          "object models")


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
