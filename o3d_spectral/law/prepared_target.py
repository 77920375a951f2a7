"""A target prepared once, against which many sources are registered.

Registering many models to one scene (every object of a catalogue in one capture), or
one view after another to a reference (tracking, the servo's goal view), repeats the
target's preparation on every call: its down-sampling, its normals, its voxel grid and
their spectra, its EGI at every smoothing level. :func:`prepare_target` does it once;
both registration calls accept the :class:`PreparedTarget` in place of the target and
give the same result as with the cloud itself::

    scene = o3d_spectral.prepare_target(scene_cloud, voxel_size=0.008)
    for model in models:
        result = o3d_spectral.registration_spectral_global(model, scene, 0.008)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..common.checks import check_instance, check_voxel_size
from ..correlation.device import Device, parse_device
from ..io.cloud import CloudArrays, as_arrays
from ..io.density import read_at_voxels
from ..options import CloudOption, SpectralRegistrationOption
from . import centring
from .prepared import check_prepared_with
from .stepper import SpectralStepper

__all__ = ["PreparedTarget", "prepare_target"]


@dataclass(frozen=True)
class PreparedTarget:
    """A target cloud with what the registration derives from it alone.

    Build it with :func:`prepare_target`. Its spectra are shared by the calls that use it,
    also from several threads (they only read them).

    Attributes
    ----------
    arrays : CloudArrays
        The target's points and normals as given, metres (a copy).
    voxel_size : float
        The voxel size it was prepared for, metres.
    option : SpectralRegistrationOption
        The representation its spectra were made with.
    cloud : CloudOption
        The normal estimation and sensor positions its preparation used.
    offset : ndarray, shape (3,), or None
        Where the registration centres clouds given far from the origin, metres
        (:mod:`o3d_spectral.law.centring`); None near it.
    stepper : SpectralStepper
        The target's spectra, in that centred frame.
    """

    arrays: CloudArrays
    voxel_size: float
    option: SpectralRegistrationOption
    cloud: CloudOption
    offset: NDArray[np.float64] | None
    stepper: SpectralStepper

    @property
    def device(self) -> Device:
        """Where the search's correlations against it run (its spectra live there)."""
        return self.stepper.device

    def check(
        self, voxel_size: float, option: SpectralRegistrationOption | None,
        cloud: CloudOption | None, device: object | None = None,
    ) -> None:
        """``ValueError`` naming ``target`` when a call's settings differ from those it
        was prepared with (a call that names no device uses the target's)."""
        asked = {"voxel_size": float(voxel_size),
                 "option": option or SpectralRegistrationOption(),
                 "cloud": cloud or CloudOption()}
        if device is not None:
            asked["device"] = parse_device(device)
        check_prepared_with("target", self, asked)


def prepare_target(
    target: object, voxel_size: float, option: SpectralRegistrationOption | None = None, *,
    cloud: CloudOption | None = None, device: object | None = None,
) -> PreparedTarget:
    """Prepare ``target`` once for many registrations at ``voxel_size``.

    Parameters
    ----------
    target : PointCloud, tensor PointCloud or ndarray
        As for :func:`o3d_spectral.registration_spectral_global`; not modified.
    voxel_size : float
        Voxel edge, metres: the calls must use the same.
    option : SpectralRegistrationOption, optional
        The representation; the calls must use the same.
    cloud : CloudOption, optional
        Normal estimation and sensor positions; the calls must use the same.
    device : str or open3d.core.Device, optional
        Where the search's correlations against it run (``"CPU:0"``, ``"CUDA:0"``); the
        calls use it.

    Returns
    -------
    PreparedTarget
        Accepted as ``target`` by :func:`o3d_spectral.registration_spectral` and
        :func:`o3d_spectral.registration_spectral_global`.

    Raises
    ------
    ValueError, TypeError
        As the registration calls, for the target, the voxel size and the settings.
    """
    voxel_size = check_voxel_size(voxel_size)
    check_instance("option", option, SpectralRegistrationOption)
    check_instance("cloud", cloud, CloudOption)
    option, cloud = option or SpectralRegistrationOption(), cloud or CloudOption()
    arrays = as_arrays(target, "target")
    read, _ = read_at_voxels(arrays, voxel_size)  # as the calls read it
    c = centring.offset(read)
    centred, centred_cloud, origin = read, cloud, None
    if c is not None:  # as the calls do: a frame centred on the target
        centred = centring.centred_arrays(read, c)
        centred_cloud, origin = centring.centred_option(cloud, c), -c
    stepper = SpectralStepper(centred, voxel_size, option=option, cloud=centred_cloud,
                              frame_origin=origin, device=device)
    return PreparedTarget(arrays, float(voxel_size), option, cloud, c, stepper)
