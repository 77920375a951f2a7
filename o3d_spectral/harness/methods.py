"""Registration methods of the evaluation harness, registered by name.

Every method has the signature ``(source, target, voxel_size, seed) -> (transformation,
info)``:

* ``source``, ``target``: ``open3d.geometry.PointCloud`` with normals, metres (not modified);
* ``voxel_size``: the voxel edge (m) every method down-samples to;
* ``seed``: the seed of the method's randomness (a method without any ignores it);
* ``transformation``: 4x4 float64 source-to-target estimate;
* ``info``: a dict with any of the keys in :data:`INFO_KEYS`.

A new method is one decorated function::

    @register_method("my_method", settings={"max_iteration": 50})
    def my_method(source, target, voxel_size, seed):
        ...
        return transformation, {"iterations": 12}

and a new spectral variant one call to :func:`register_spectral_variant`. ``settings``
describes the method's fixed parameters (distances in voxels); every run records them
(:func:`method_settings`).
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable
from typing import Any

import numpy as np
import open3d as o3d

from o3d_spectral import (
    CloudOption,
    GlobalSearchOption,
    SpectralConvergenceCriteria,
    SpectralRegistrationOption,
    registration_spectral,
    registration_spectral_global,
)
from o3d_spectral.harness.tutorial import (
    FPFH,
    RANSAC,
    REFINEMENT,
    global_then_refine,
    open3d_fields,
    ransac_matcher,
)
from o3d_spectral.registration import DEFAULT_REFINEMENT

__all__ = [
    "INFO_KEYS",
    "Method",
    "get_method",
    "method_names",
    "method_settings",
    "register_method",
    "register_spectral_variant",
]

Method = Callable[
    [o3d.geometry.PointCloud, o3d.geometry.PointCloud, float, int], tuple[np.ndarray, dict]
]

#: What a method may report in its ``info`` dict: ``iterations`` (int), ``converged``
#: (bool), ``translation_gradient_norm`` (m), ``rotation_gradient_norm`` (rad), both of the
#: last iteration, and ``trajectory`` (ndarray (K, 4, 4): the estimate at the start of each
#: iteration, turned into error curves by the runner).
INFO_KEYS = ("iterations", "converged", "translation_gradient_norm", "rotation_gradient_norm",
             "trajectory", "confidence")


@dataclasses.dataclass(frozen=True)
class _Entry:
    method: Method
    settings: str  # JSON text, so that no caller can change the stored settings


_REGISTRY: dict[str, _Entry] = {}
#: Known methods whose package is missing here: how to install it, by name.
UNAVAILABLE: dict[str, str] = {}

_reg = o3d.pipelines.registration

#: ICP from the identity: correspondences up to this many voxels away, at most this many
#: iterations (Open3D's default 30 stops before a 10 cm offset is closed).
ICP_DISTANCE_VOXELS = 5.0
ICP_MAX_ITERATION = 100


def _json_value(value: Any) -> Any:
    """NumPy arrays and scalars as JSON values (``json.dumps``' ``default``)."""
    if isinstance(value, np.ndarray | np.generic):
        return value.tolist()
    raise TypeError(f"{type(value).__name__} is not JSON-able: {value!r}")


def register_method(name: str, *, settings: dict | None = None) -> Callable[[Method], Method]:
    """Decorator registering a method under ``name`` (see the module docstring).

    Parameters
    ----------
    name : str
        An identifier not registered yet.
    settings : dict, optional
        The method's fixed parameters, JSON-able (NumPy values are turned into lists and
        numbers); recorded in every run's ``config.json``. Empty when omitted.

    Raises
    ------
    ValueError
        If ``name`` is empty or already registered.
    TypeError
        If ``settings`` is not JSON-able.
    """
    if not name or not name.isidentifier():
        raise ValueError(f"name must be a non-empty identifier, got {name!r}")
    if name in _REGISTRY:
        raise ValueError(f"name {name!r} is already registered; pick another one")
    text = json.dumps({} if settings is None else settings, default=_json_value)

    def decorate(method: Method) -> Method:
        _REGISTRY[name] = _Entry(method, text)
        return method

    return decorate


def _entry(name: str) -> _Entry:
    try:
        return _REGISTRY[name]
    except KeyError:
        if name in UNAVAILABLE:
            raise ValueError(f"method {name!r} needs {UNAVAILABLE[name]}") from None
        raise ValueError(
            f"method {name!r} is not registered; choose from {', '.join(method_names())}"
        ) from None


def get_method(name: str) -> Method:
    """The method registered under ``name``; ``ValueError`` listing the names if unknown."""
    return _entry(name).method


def method_settings(name: str) -> dict:
    """The settings the method ``name`` was registered with (a new copy, JSON values);
    ``ValueError`` listing the names if unknown."""
    return json.loads(_entry(name).settings)


def method_names() -> tuple[str, ...]:
    """Names of the registered methods, in registration order."""
    return tuple(_REGISTRY)


def register_spectral_variant(name: str, *, global_search: bool = False, **settings) -> Method:
    """Register a spectral call with fixed settings as ``name``: the local call
    (:func:`o3d_spectral.registration_spectral` from the identity) or, with
    ``global_search``, :func:`o3d_spectral.registration_spectral_global`.

    ``settings`` are the call's keyword arguments (``option``, ``criteria``, ``search``,
    ``cloud``, ``refinement``). The method is deterministic and ignores its seed; its
    ``info`` holds every key of :data:`INFO_KEYS`.
    """
    call = registration_spectral_global if global_search else registration_spectral

    def spectral(source, target, voxel_size: float, seed: int) -> tuple[np.ndarray, dict]:
        result = call(source, target, voxel_size, **settings)
        history = result.history  # empty when the global call confirmed its first pose
        last = history[-1] if history else None
        info = {
            "iterations": result.num_iterations,
            "converged": result.converged,
            "translation_gradient_norm": last.translation_gradient_norm if last else 0.0,
            "rotation_gradient_norm": last.rotation_gradient_norm if last else 0.0,
            "trajectory": np.stack([record.transformation for record in history]
                                   or [np.asarray(result.transformation)]),
            "confidence": result.confidence if global_search else None,
        }
        return np.asarray(result.transformation), info

    described = ", ".join(f"{key}={value!r}" for key, value in settings.items())
    spectral.__doc__ = f"{call.__name__} with {described or 'its defaults'}."
    return register_method(name, settings=_spectral_settings(call, settings))(spectral)


def _spectral_settings(call: Callable, settings: dict) -> dict:
    """Every setting a spectral call runs with, as JSON-able dicts: the given ones and
    the defaults of those not given (``refinement`` None when switched off)."""
    defaults = {
        "option": SpectralRegistrationOption(),
        "criteria": SpectralConvergenceCriteria(),
        "cloud": CloudOption(),
        "refinement": DEFAULT_REFINEMENT,
    }
    if call is registration_spectral_global:
        defaults["search"] = GlobalSearchOption()
    chosen = {**defaults, **settings}
    return {"call": call.__name__} | {
        key: None if value is None else dataclasses.asdict(value) for key, value in chosen.items()
    }


register_spectral_variant("spectral")
register_spectral_variant(
    "spectral_paper",
    option=SpectralRegistrationOption.paper(),
    cloud=CloudOption(target_viewpoint=None),
    refinement=None,
)
register_spectral_variant("spectral_global", global_search=True)
register_spectral_variant("spectral_global_unrefined", global_search=True, refinement=None)
register_spectral_variant(  # the search without search_visibility and focus_places
    "spectral_global_whole_egi",
    global_search=True,
    search=GlobalSearchOption(search_visibility=False, focus_places=1),
)


#: The ICP baselines' settings (distances in voxels).
_ICP_SETTINGS = {
    "init": "identity",
    "down_sample_voxels": 1.0,
    "max_correspondence_distance_voxels": ICP_DISTANCE_VOXELS,
    "criteria": open3d_fields(
        _reg.ICPConvergenceCriteria(max_iteration=ICP_MAX_ITERATION),
        ("max_iteration", "relative_fitness", "relative_rmse"),
    ),
}

#: FGR's options: the correspondence distance in voxels, Open3D's defaults for the rest.
_FGR_DISTANCE_VOXELS = 0.5
_FGR = {"maximum_correspondence_distance_voxels": _FGR_DISTANCE_VOXELS} | open3d_fields(
    _reg.FastGlobalRegistrationOption(),
    (
        "decrease_mu",
        "division_factor",
        "iteration_number",
        "maximum_tuple_count",
        "tuple_scale",
        "tuple_test",
        "use_absolute_scale",
    ),
)


def _down_sampled(cloud: o3d.geometry.PointCloud, voxel_size: float) -> o3d.geometry.PointCloud:
    """Voxel down-sampling keeping the given normals (re-normalised after averaging)."""
    down = cloud.voxel_down_sample(voxel_size)
    down.normalize_normals()
    return down


def _icp_from_identity(source, target, voxel_size: float, estimation) -> tuple[np.ndarray, dict]:
    result = _reg.registration_icp(
        _down_sampled(source, voxel_size),
        _down_sampled(target, voxel_size),
        ICP_DISTANCE_VOXELS * voxel_size,
        np.eye(4),
        estimation,
        _reg.ICPConvergenceCriteria(max_iteration=ICP_MAX_ITERATION),
    )
    return np.asarray(result.transformation), {}


@register_method("icp_point_to_point", settings={"estimation": "point_to_point", **_ICP_SETTINGS})
def icp_point_to_point(source, target, voxel_size: float, seed: int) -> tuple[np.ndarray, dict]:
    """Open3D point-to-point ICP from the identity on clouds down-sampled at the voxel size."""
    estimation = _reg.TransformationEstimationPointToPoint()
    return _icp_from_identity(source, target, voxel_size, estimation)


@register_method("icp_point_to_plane", settings={"estimation": "point_to_plane", **_ICP_SETTINGS})
def icp_point_to_plane(source, target, voxel_size: float, seed: int) -> tuple[np.ndarray, dict]:
    """Open3D point-to-plane ICP from the identity (the clouds' own normals)."""
    return _icp_from_identity(
        source, target, voxel_size, _reg.TransformationEstimationPointToPlane()
    )


@register_method(
    "fpfh_ransac", settings={"features": FPFH, "ransac": RANSAC, "refinement": REFINEMENT}
)
def fpfh_ransac(source, target, voxel_size: float, seed: int) -> tuple[np.ndarray, dict]:
    """Open3D's global-registration tutorial: FPFH + RANSAC, then point-to-plane ICP.

    Mutual filter, inlier distance ``1.5 v``, edge-length (0.9) and distance checkers,
    3-point samples, at most 100000 iterations at confidence 0.999.
    """
    return global_then_refine(source, target, voxel_size, seed, ransac_matcher(voxel_size)), {}


@register_method("fgr", settings={"features": FPFH, "fgr": _FGR, "refinement": REFINEMENT})
def fgr(source, target, voxel_size: float, seed: int) -> tuple[np.ndarray, dict]:
    """Open3D Fast Global Registration on the tutorial's FPFH features (distance
    ``0.5 v``), then the same point-to-plane ICP refinement."""
    option = _reg.FastGlobalRegistrationOption(
        maximum_correspondence_distance=_FGR_DISTANCE_VOXELS * voxel_size
    )

    def fast_global(source_down, target_down, source_fpfh, target_fpfh):
        return _reg.registration_fgr_based_on_feature_matching(
            source_down, target_down, source_fpfh, target_fpfh, option
        )

    return global_then_refine(source, target, voxel_size, seed, fast_global), {}


# Peers from other packages and the tuned FPFH-RANSAC, registered after Open3D's methods.
from o3d_spectral.harness import peers  # noqa: E402, F401
