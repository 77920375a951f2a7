"""A source prepared once and registered to many targets.

Registering one model to many scans (pose estimation over a sequence, a robot that looks
for the same part in every capture) repeats the source's preparation on every call: its
down-sampling, its normals (estimated, and their signs chosen, when it has none) and the
cells its EGI is made from. :func:`prepare` does it once; both registration calls accept
the :class:`PreparedSource` in place of the source and give the same result as with the
cloud itself, to rounding (the calls work in a frame centred on the target, into which
the prepared cloud is moved)::

    model = o3d_spectral.prepare(model_cloud, voxel_size=0.008)
    for scan in scans:
        result = o3d_spectral.registration_spectral_global(model, scan, 0.008)
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..common.checks import check_instance, check_number, check_voxel_span
from ..io.cloud import CloudArrays, PreparedCloud, as_arrays
from ..io.cloud import prepare as prepare_arrays
from ..io.density import read_at_voxels
from ..io.rows import largest_side
from ..options import CloudOption, SpectralRegistrationOption

__all__ = ["PreparedSource", "prepare", "prepared_cloud", "check_prepared_with"]


def check_prepared_with(argument: str, prepared: object, asked: dict[str, object]) -> None:
    """``ValueError`` naming ``argument`` when a setting a call ``asked`` for (name ->
    value) differs from the attribute of that name ``prepared`` was made with."""
    for name, value in asked.items():
        if getattr(prepared, name) != value:
            raise ValueError(
                f"{argument} was prepared with {name}={getattr(prepared, name)!r}, the call "
                f"asks for {value!r}: prepare it with the call's settings")


def prepared_cloud(
    cloud: object, voxel_size: float, *, egi_voxel_size: float | None,
    normal_radius: float | None, camera_location: ArrayLike | None, origin: ArrayLike,
    name: str,
) -> PreparedCloud:
    """``cloud`` checked (it must span 4 voxels, and no more than a grid holds) and prepared
    (:func:`o3d_spectral.io.cloud.prepare`, whose arguments these are)."""
    arrays = as_arrays(cloud, name)
    extent = largest_side(arrays.points)
    check_voxel_span(voxel_size, extent, name)
    if egi_voxel_size is not None:  # the same bounds as the voxel's, for its cells
        check_voxel_span(egi_voxel_size, extent, name, "egi_voxel_size")
    return prepare_arrays(
        arrays, voxel_size, egi_voxel_size=egi_voxel_size, normal_radius=normal_radius,
        camera_location=camera_location, origin=origin, name=name,
    )


@dataclass(frozen=True)
class PreparedSource:
    """A source cloud with what the registration derives from it alone.

    Build it with :func:`prepare`. Attributes are read-only, the prepared cloud's arrays
    too (not writeable: an edit would move every later result).

    Attributes
    ----------
    arrays : CloudArrays
        The source's points and normals as given, metres (a copy).
    voxel_size : float
        The voxel size it was prepared for, metres.
    egi_voxel_size, normal_radius : float or None
        The settings its preparation used (:class:`SpectralRegistrationOption`,
        :class:`CloudOption`).
    camera_location : tuple of 3 float or None
        The source's sensor position its normals were oriented towards, metres.
    cloud : PreparedCloud
        The down-sampled points, their normals and the EGI's normals, in the source's
        own frame.
    """

    arrays: CloudArrays
    voxel_size: float
    egi_voxel_size: float | None
    normal_radius: float | None
    camera_location: tuple[float, float, float] | None
    cloud: PreparedCloud

    def __post_init__(self) -> None:
        for field in dataclasses.fields(self.cloud):
            value = getattr(self.cloud, field.name)
            if isinstance(value, np.ndarray):
                value.flags.writeable = False

    def check(
        self, voxel_size: float, option: SpectralRegistrationOption | None,
        cloud: CloudOption | None,
    ) -> None:
        """``ValueError`` naming ``source`` when a call's settings differ from those it
        was prepared with."""
        option, cloud = option or SpectralRegistrationOption(), cloud or CloudOption()
        asked = {"voxel_size": float(voxel_size), "egi_voxel_size": option.egi_voxel_size,
                 "normal_radius": cloud.normal_radius,
                 "camera_location": cloud.source_camera}
        check_prepared_with("source", self, asked)

    def moved(self, offset: NDArray[np.float64]) -> PreparedCloud:
        """The prepared cloud with its points moved by ``-offset`` (metres; the frame a
        registration centres far-away clouds in, :mod:`o3d_spectral.law.centring`)."""
        return dataclasses.replace(self.cloud, points=self.cloud.points - offset,
                                   normal_points=self.cloud.normal_points - offset)


def prepare(
    source: object, voxel_size: float, option: SpectralRegistrationOption | None = None, *,
    cloud: CloudOption | None = None,
) -> PreparedSource:
    """Prepare ``source`` once for many registrations at ``voxel_size``.

    Parameters
    ----------
    source : PointCloud, tensor PointCloud or ndarray
        As for :func:`o3d_spectral.registration_spectral_global`; not modified.
    voxel_size : float
        Voxel edge, metres: the calls must use the same.
    option : SpectralRegistrationOption, optional
        Its ``egi_voxel_size`` is used; the calls must use the same.
    cloud : CloudOption, optional
        Its ``normal_radius`` and the source's sensor position are used; the calls must
        use the same.

    Returns
    -------
    PreparedSource
        Accepted as ``source`` by :func:`o3d_spectral.registration_spectral` and
        :func:`o3d_spectral.registration_spectral_global`.

    Raises
    ------
    ValueError, TypeError
        As the registration calls, for the source, the voxel size and the settings.
    """
    check_number("voxel_size", voxel_size, low=0.0, low_open=True)
    check_instance("option", option, SpectralRegistrationOption)
    check_instance("cloud", cloud, CloudOption)
    option, cloud = option or SpectralRegistrationOption(), cloud or CloudOption()
    arrays = as_arrays(source, "source")
    camera = cloud.source_camera
    read, _ = read_at_voxels(arrays, float(voxel_size))  # as the calls read it
    prepared = prepared_cloud(
        read, float(voxel_size), egi_voxel_size=option.egi_voxel_size,
        normal_radius=cloud.normal_radius, camera_location=camera, origin=np.zeros(3),
        name="source",
    )
    return PreparedSource(arrays, float(voxel_size), option.egi_voxel_size,
                          cloud.normal_radius, camera, prepared)
