"""Checks of a results row as it is read back (:mod:`o3d_spectral.harness.records`).

Every row must hold its key, and its fields must be of their JSON type; a report also
needs every row's ``success`` (:func:`first_without`): a row without it would be read as
NaN (counted as a success), and ``"success": "yes"`` would fail deep in pandas without
naming the file.
"""

from __future__ import annotations

from collections.abc import Iterable
from numbers import Real
from pathlib import Path

__all__ = ["check_row", "first_without"]

#: Fields every row holds (its key), and what each must be.
_REQUIRED = {"suite": "a string", "index": "an integer", "method": "a string"}
#: Fields a row may hold, and what each must be.
_TYPED = {"success": "true or false", "time_s": "a number"}
#: Fields a row may hold, null or a number.
_NUMBERS = ("rotation_error_deg", "translation_error_m", "rotation_error_sym_deg",
            "translation_error_sym_m", "squared_translation_error_m2",
            "squared_rotation_error_rad2", "confidence", "fitness", "inlier_rmse")


def _is(value: object, kind: str) -> bool:
    if kind == "a string":
        return isinstance(value, str)
    if kind == "true or false":
        return isinstance(value, bool)
    if kind == "an integer":
        return isinstance(value, int) and not isinstance(value, bool)
    return isinstance(value, Real) and not isinstance(value, bool)


def check_row(row: object, where: str) -> dict:
    """``row`` when it is a results row, else ``ValueError`` naming ``where`` (the file
    and line) and the field missing or of the wrong type."""
    if not isinstance(row, dict):
        raise ValueError(f"{where}: not a results row (a JSON object); remove that line")
    for field, kind in _REQUIRED.items():
        if field not in row:
            raise ValueError(f"{where}: not a results row: no {field!r}; fix or remove that line")
        if not _is(row[field], kind):
            raise ValueError(f"{where}: {field!r} must be {kind}, got {row[field]!r}; fix or "
                             "remove that line")
    for field, kind in _TYPED.items():
        if field in row and not _is(row[field], kind):
            raise ValueError(f"{where}: {field!r} must be {kind}, got {row[field]!r}; fix or "
                             "remove that line")
    for field in _NUMBERS:
        if row.get(field) is not None and not _is(row[field], "a number"):
            raise ValueError(f"{where}: {field!r} must be a number or null, got "
                             f"{row[field]!r}; fix or remove that line")
    return row


def first_without(files: Iterable[Path], field: str) -> str | None:
    """Where (``"file, line n"``) the first row of ``files`` without ``field`` is, None
    when every row has it (rows are read as ``records`` reads them, whole lines only)."""
    for file in files:
        text = file.read_text()
        for number, line in enumerate(text[: text.rfind("\n") + 1].splitlines(), 1):
            if line.strip() and f'"{field}"' not in line:
                return f"{file}, line {number}"
    return None
