"""Synthetic data: the bundled object models, a virtual depth camera, scenes and suites.

* :mod:`~o3d_spectral.synthetic.models`: the bundled YCB meshes (``load_model``);
* :mod:`~o3d_spectral.synthetic.symmetry`: the models' symmetry groups, found on the meshes;
* :mod:`~o3d_spectral.synthetic.sensor`: pinhole intrinsics and the depth-noise model;
* :mod:`~o3d_spectral.synthetic.camera`: the virtual depth camera (raycasting, scans);
* :mod:`~o3d_spectral.synthetic.sampling`: random model clouds, surface points, rotations;
* :mod:`~o3d_spectral.synthetic.instance`: ``Instance`` and the generator's ``SceneOptions``;
* :mod:`~o3d_spectral.synthetic.occlusion`: what a view sees of an object, occluders;
* :mod:`~o3d_spectral.synthetic.tabletop`: the table and objects resting on it;
* :mod:`~o3d_spectral.synthetic.scenes`: one registration instance per condition;
* :mod:`~o3d_spectral.synthetic.suite`: seeded suites of instances on disk.

The names below are imported from their modules on first access, so that importing one
module does not import them all.
"""

from o3d_spectral.common.lazy import lazy_attributes, lazy_dir

__all__ = [
    "CONDITIONS",
    "CameraIntrinsics",
    "DepthNoise",
    "Instance",
    "SceneOptions",
    "Suite",
    "Symmetry",
    "instance_rng",
    "load_model",
    "load_suite",
    "look_at",
    "make_instance",
    "make_suite",
    "model_names",
    "model_symmetry",
    "render",
    "scan_meshes",
    "table_mesh",
    "tabletop",
]

__getattr__ = lazy_attributes(
    __name__,
    {
        "CONDITIONS": "instance",
        "CameraIntrinsics": "sensor",
        "DepthNoise": "sensor",
        "Instance": "instance",
        "SceneOptions": "instance",
        "Suite": "suite",
        "Symmetry": "symmetry",
        "instance_rng": "suite",
        "load_model": "models",
        "load_suite": "suite",
        "look_at": "camera",
        "make_instance": "scenes",
        "make_suite": "suite",
        "model_names": "models",
        "model_symmetry": "symmetry",
        "render": "camera",
        "scan_meshes": "camera",
        "table_mesh": "tabletop",
        "tabletop": "tabletop",
    },
)
__dir__ = lazy_dir(globals(), __all__)
