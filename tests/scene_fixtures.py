"""Registration problems stored in ``tests/data/`` (written by ``tests/data/make_fixtures.py``).

A test that shows a behaviour on one particular scene reads the scene from a file, so that
a change to the scene generator (its random stream, its sensor model) leaves the test's
input as it was. Each file holds the source and target clouds (points quantised to
:data:`STEP` metres and delta-coded in their stored order, normals to 1/127), the ground
truth and the model's pose in the source frame, in a compressed ``.npz``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import open3d as o3d

from o3d_spectral.synthetic.instance import Instance

DATA = Path(__file__).resolve().parent / "data"
#: Quantisation step of the stored points (m): an eightieth of the tests' 8 mm voxel and
#: a tenth of the simulated sensor's depth step.
STEP = 1e-4


def _encoded(cloud: o3d.geometry.PointCloud, prefix: str) -> dict[str, np.ndarray]:
    points, normals = np.asarray(cloud.points), np.asarray(cloud.normals)
    origin = points.min(axis=0)
    steps = np.round((points - origin) / STEP).astype(np.int32)
    return {
        f"{prefix}_origin": origin,
        f"{prefix}_steps": np.diff(steps, axis=0, prepend=np.zeros((1, 3), np.int32)),
        f"{prefix}_normals": np.round(normals * 127.0).astype(np.int8),
    }


def _decoded(data: np.lib.npyio.NpzFile, prefix: str) -> o3d.geometry.PointCloud:
    points = data[f"{prefix}_origin"] + STEP * np.cumsum(data[f"{prefix}_steps"], axis=0)
    normals = data[f"{prefix}_normals"].astype(np.float64)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    cloud.normals = o3d.utility.Vector3dVector(normals)
    return cloud


def save_scene(instance: Instance, path: Path, note: str) -> None:
    """Store ``instance`` (clouds, ground truth, model pose, object, condition) at
    ``path``; ``note`` says where it came from."""
    np.savez_compressed(
        path,
        **_encoded(instance.source, "source"),
        **_encoded(instance.target, "target"),
        T_gt=instance.T_gt,
        source_from_model=instance.source_from_model,
        object=instance.object,
        condition=instance.metadata["condition"],
        note=note,
    )


def load_scene(name: str) -> Instance:
    """The stored scene ``tests/data/<name>.npz`` as an :class:`Instance` (no target
    labels: every point reads -1)."""
    with np.load(DATA / f"{name}.npz") as data:
        source, target = _decoded(data, "source"), _decoded(data, "target")
        metadata = {
            "object": str(data["object"]),
            "condition": str(data["condition"]),
            "note": str(data["note"]),
        }
        return Instance(
            source=source,
            target=target,
            T_gt=data["T_gt"],
            target_labels=np.full(len(target.points), -1),
            source_from_model=data["source_from_model"],
            metadata=metadata,
        )
