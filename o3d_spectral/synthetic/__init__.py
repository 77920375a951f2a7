"""Synthetic data: the bundled object models, a virtual depth camera, scenes and suites.

* :mod:`~o3d_spectral.synthetic.models`: the bundled YCB meshes (``load_model``);
* :mod:`~o3d_spectral.synthetic.camera`: the virtual depth camera (raycasting, noise);
* :mod:`~o3d_spectral.synthetic.scenes`: one registration instance per condition;
* :mod:`~o3d_spectral.synthetic.suite`: seeded suites of instances on disk.

The names below are imported from their modules on first access.
"""

from o3d_spectral._lazy import lazy_attributes

_WHERE = {
    "load_model": "models",
    "model_names": "models",
    "model_path": "models",
    "objects_dir": "models",
    "CameraIntrinsics": "camera",
    "DepthNoise": "camera",
    "look_at": "camera",
    "render": "camera",
    "scan_meshes": "camera",
    "CONDITIONS": "scenes",
    "Instance": "scenes",
    "SceneOptions": "scenes",
    "make_instance": "scenes",
    "table_mesh": "scenes",
    "tabletop": "scenes",
    "Suite": "suite",
    "instance_rng": "suite",
    "load_suite": "suite",
    "make_suite": "suite",
}
__all__ = list(_WHERE)
__getattr__ = lazy_attributes(__name__, _WHERE)
