"""Checks of the entries of a BOP dataset's JSON files (:mod:`o3d_spectral.harness.bop`):
each returns the value read, or raises a ``ValueError`` naming the file, the entry and
the field, as the suites' manifests are checked (:mod:`o3d_spectral.synthetic.manifest`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from o3d_spectral.synthetic.manifest import MAX_TRANSLATION, check_pose

__all__ = ["array", "entry_pose", "image_id", "integer", "listed_targets", "number",
           "visible_fraction"]

#: Millimetres, BOP's unit, in metres.
_MM = 1e-3


def integer(value: object, where: str, field: str) -> int:
    """``value``, a JSON integer, else ``ValueError`` naming ``where`` and ``field``."""
    if not isinstance(value, int) or isinstance(value, bool):
        raise ValueError(f"{where}: {field} must be an integer, got {value!r}")
    return value


def number(value: object, where: str, field: str) -> float:
    """``value``, a finite JSON number, else ``ValueError`` naming ``where`` and ``field``."""
    if not isinstance(value, int | float) or isinstance(value, bool) or not np.isfinite(value):
        raise ValueError(f"{where}: {field} must be a finite number, got {value!r}")
    return float(value)


def image_id(key: str, path: Path) -> int:
    if not key.isdigit():
        raise ValueError(f"{path}: image key {key!r} is not an image id (digits)")
    return int(key)


def array(value: object, shape: tuple[int, ...], where: str, field: str) -> np.ndarray:
    """``value`` as finite numbers of ``shape``, else ``ValueError`` naming the field."""
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        array = None
    if array is None or array.size != np.prod(shape) or not np.all(np.isfinite(array)):
        raise ValueError(f"{where}: {field} must be {np.prod(shape)} finite numbers "
                         f"({'x'.join(map(str, shape))}), got {value!r}"[:300])
    return array.reshape(shape)


def entry_pose(entry: dict, where: str) -> np.ndarray:
    """The model-to-camera pose (m) of a ``scene_gt.json`` entry, checked to be rigid."""
    T = np.eye(4)
    T[:3, :3] = array(entry.get("cam_R_m2c"), (3, 3), where, "cam_R_m2c")
    check_pose(where, "cam_R_m2c", T, atol=1e-4)  # BOP prints rotations to a few digits
    translation = array(entry.get("cam_t_m2c"), (3,), where, "cam_t_m2c")
    if np.max(np.abs(translation)) > MAX_TRANSLATION:
        raise ValueError(f"{where}: cam_t_m2c must be under {MAX_TRANSLATION:g} mm, got "
                         f"{translation.tolist()}")
    T[:3, 3] = _MM * translation
    return T


def visible_fraction(info: dict, image: str, k: int, path: Path) -> float | None:
    """``visib_fract`` of annotation ``k`` of ``image`` in ``scene_gt_info.json``."""
    where = f"{path}, image {image}, annotation {k}"
    entries = info.get(image)
    if not isinstance(entries, list) or len(entries) <= k or not isinstance(entries[k], dict):
        raise ValueError(f"{where}: missing (scene_gt_info.json lists fewer annotations than "
                         "scene_gt.json)")
    value = entries[k].get("visib_fract")
    return None if value is None else number(value, where, "visib_fract")


def listed_targets(document: object, path: Path) -> set[tuple[int, int, int]]:
    """The (scene, image, object) of ``test_targets_bop19.json``, checked."""
    if not isinstance(document, list):
        raise ValueError(f"{path}: expected a list of targets")
    listed = set()
    for n, target in enumerate(document):
        where = f"{path}, target {n}"
        if not isinstance(target, dict):
            raise ValueError(f"{where}: expected an object (scene_id, im_id, obj_id)")
        listed.add(tuple(integer(target.get(f), where, f) for f in ("scene_id", "im_id",
                                                                     "obj_id")))
    return listed
