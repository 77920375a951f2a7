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

The methods this package ships are one explicit list, :func:`builtin_methods`: the
spectral variants, Open3D's methods (:mod:`~o3d_spectral.harness.baselines`) and the peers
from other packages (:mod:`~o3d_spectral.harness.peers`), registered when this module is
first imported; neither of those modules registers anything itself.
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
from o3d_spectral.harness import baselines, peers
from o3d_spectral.registration import DEFAULT_REFINEMENT

__all__ = [
    "INFO_KEYS",
    "UNAVAILABLE",
    "Method",
    "builtin_methods",
    "get_method",
    "method_names",
    "method_settings",
    "register_method",
    "register_spectral_variant",
    "spectral_variant",
    "unregister_method",
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

#: Re-exported: the ICP baselines' distance (voxels) and iteration limit.
ICP_DISTANCE_VOXELS = baselines.ICP_DISTANCE_VOXELS
ICP_MAX_ITERATION = baselines.ICP_MAX_ITERATION

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


def unregister_method(name: str) -> None:
    """Remove the method registered under ``name``; ``ValueError`` listing the names if
    unknown."""
    _entry(name)
    del _REGISTRY[name]


def spectral_variant(*, global_search: bool = False, **settings) -> tuple[Method, dict]:
    """A spectral call with fixed settings as a harness method, and its settings: the
    local call (:func:`o3d_spectral.registration_spectral` from the identity) or, with
    ``global_search``, :func:`o3d_spectral.registration_spectral_global`.

    ``settings`` are the call's keyword arguments (``option``, ``criteria``, ``search``,
    ``cloud``, ``refinement``). The method is deterministic and ignores its seed; its
    ``info`` holds every key of :data:`INFO_KEYS`. The settings returned are every
    setting the call runs with (the defaults of those not given), as JSON-able dicts.
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
    return spectral, _spectral_settings(call, settings)


def register_spectral_variant(name: str, *, global_search: bool = False, **settings) -> Method:
    """Register :func:`spectral_variant` ``(global_search=..., **settings)`` as ``name``
    and return the method."""
    method, described = spectral_variant(global_search=global_search, **settings)
    return register_method(name, settings=described)(method)


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


def builtin_methods() -> list[tuple[str, Method, dict]]:
    """The methods this package registers, in order: name, method, settings.

    The spectral variants, Open3D's methods, the peers whose package imports here and
    FPFH-RANSAC with tuned features; the missing peers are in :data:`UNAVAILABLE`.
    """
    spectral = [
        ("spectral", {}),
        ("spectral_paper", {
            "option": SpectralRegistrationOption.paper(),
            "cloud": CloudOption(target_viewpoint=None),
            "refinement": None,
        }),
        ("spectral_global", {"global_search": True}),
        ("spectral_global_unrefined", {"global_search": True, "refinement": None}),
        # the search without search_visibility and focus_places
        ("spectral_global_whole_egi", {
            "global_search": True,
            "search": GlobalSearchOption(search_visibility=False, focus_places=1),
        }),
    ]
    found = [(name, *spectral_variant(**settings)) for name, settings in spectral]
    return [*found, *baselines.BASELINES, *peers.available_peers(), peers.TUNED]


def _register_builtins() -> None:
    for name, method, settings in builtin_methods():
        register_method(name, settings=settings)(method)
    UNAVAILABLE.update(peers.missing_peers())


_register_builtins()
