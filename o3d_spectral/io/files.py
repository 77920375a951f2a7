"""Checks of cloud files before Open3D reads them, and of what it read.

Open3D's readers do not report a failure to Python: a truncated binary PLY comes back
with its declared number of points, the missing ones uninitialised (garbage or zeros),
and a header claiming 1e9 vertices makes it allocate them before reading. So the header
of a PLY or PCD file is read here first and the file's size checked against what it
declares; what Open3D returns is then checked for non-finite coordinates. Every error
is a ``ValueError`` (``FileNotFoundError`` for a missing file) naming the file.

:func:`atomic_write_text` replaces a file whole (a suite's manifest, a run's session
files and table), never leaving half of it, and :func:`atomic_write_cloud` a cloud file
(written by a writer given, checked, then renamed: Open3D's writers report success on a
full disk); they import neither Open3D nor the harness.
"""

from __future__ import annotations

import logging
import os
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

__all__ = ["atomic_write_cloud", "atomic_write_text", "check_cloud_file", "check_finite"]

log = logging.getLogger(__name__)

#: Bytes of each PLY scalar type.
_PLY_SIZES = {
    "char": 1, "int8": 1, "uchar": 1, "uint8": 1,
    "short": 2, "int16": 2, "ushort": 2, "uint16": 2,
    "int": 4, "int32": 4, "uint": 4, "uint32": 4, "float": 4, "float32": 4,
    "double": 8, "float64": 8,
}
#: A header longer than this is not a cloud file's header.
_MAX_HEADER = 1 << 16


def _corrupt(path: Path, why: str) -> ValueError:
    return ValueError(f"{path}: {why}; the file is truncated or corrupt, write it again")


def _header(path: Path, end: bytes) -> tuple[list[str], int]:
    """The header's lines up to the one starting with ``end``, and its length in bytes."""
    with path.open("rb") as file:
        head = file.read(_MAX_HEADER)
    lines, offset = [], 0
    for raw in head.splitlines(keepends=True):
        offset += len(raw)
        line = raw.decode("ascii", errors="replace").strip()
        lines.append(line)
        if line.startswith(end.decode()) and raw.endswith(b"\n"):
            return lines, offset
    raise _corrupt(path, f"no complete header (no '{end.decode()}' line)")


def _has_lines(path: Path, start: int, rows: int) -> bool:
    """Whether ``path`` holds at least ``rows`` non-empty lines after byte ``start``."""
    count = 0
    with path.open("rb") as file:
        file.seek(start)
        for line in file:
            count += bool(line.strip())
            if count >= rows:
                return True
    return False


def _ply_row_bytes(path: Path, props: list[list[str]]) -> int:
    """Fewest bytes one binary row of an element with ``props`` takes (lists empty)."""
    size = 0
    for words in props:
        kind = words[2] if words[1] == "list" and len(words) > 2 else words[1]
        if kind not in _PLY_SIZES:
            raise _corrupt(path, f"unknown PLY property type {kind!r}")
        size += _PLY_SIZES[kind]
    return size


def _check_ply(path: Path) -> None:
    with path.open("rb") as file:
        if file.read(4) != b"ply\n":
            raise _corrupt(path, "it does not start with the PLY magic line 'ply'")
    lines, header = _header(path, b"end_header")
    fmt, elements = None, []
    for line in lines:
        words = line.split()
        if words[:1] == ["format"] and len(words) >= 2:
            fmt = words[1]
        elif words[:1] == ["element"]:
            if len(words) != 3 or not words[2].isdigit():
                raise _corrupt(path, f"bad PLY header line {line!r}")
            elements.append((words[1], int(words[2]), []))
        elif words[:1] == ["property"]:
            if not elements or len(words) < 3:
                raise _corrupt(path, f"bad PLY header line {line!r}")
            elements[-1][2].append(words)
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise _corrupt(path, f"unknown PLY format {fmt!r}")
    size = path.stat().st_size - header
    if fmt == "ascii":
        rows = sum(count for _, count, _ in elements)
        if rows and not _has_lines(path, header, rows):
            raise _corrupt(path, f"its header declares {rows} rows of data, the file holds fewer")
        return
    need = sum(count * _ply_row_bytes(path, props) for _, count, props in elements)
    if size < need:
        vertices = next((count for name, count, _ in elements if name == "vertex"), 0)
        raise _corrupt(
            path, f"its header declares {vertices} vertices ({need} bytes of data at least), "
            f"the file holds {size} bytes after the header"
        )


def _check_pcd(path: Path) -> None:
    lines, header = _header(path, b"DATA")
    fields = {line.split()[0]: line.split()[1:] for line in lines if line.split()}
    try:
        points = int(fields["POINTS"][0])
        data = fields["DATA"][0]
        sizes = [int(s) for s in fields["SIZE"]]
        counts = [int(c) for c in fields.get("COUNT", ["1"] * len(sizes))]
    except (KeyError, IndexError, ValueError):
        raise _corrupt(path, "its PCD header lacks POINTS, SIZE or DATA") from None
    size = path.stat().st_size - header
    if data == "ascii":
        if points and not _has_lines(path, header, points):
            raise _corrupt(path, f"its header declares {points} points, the file holds fewer")
    elif data == "binary":
        need = points * sum(s * c for s, c in zip(sizes, counts, strict=False))
        if size < need:
            raise _corrupt(
                path, f"its header declares {points} points ({need} bytes), the file holds "
                f"{size} bytes after the header"
            )
    elif data != "binary_compressed" or size < 8:
        raise _corrupt(path, f"bad PCD DATA {data!r}")


def check_cloud_file(path: str | Path) -> Path:
    """Check that ``path`` exists and, for a PLY or PCD file, that it holds as much data as
    its header declares (before Open3D reads it). Other formats are read as text by Open3D
    and are not checked here. Returns ``path`` as a Path."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no such file: {path}")
    suffix = path.suffix.lower()
    if suffix == ".ply":
        _check_ply(path)
    elif suffix == ".pcd":
        _check_pcd(path)
    return path


def check_finite(
    points: np.ndarray, path: str | Path, *, drop: bool = False, what: str = "points",
    hint: str = "the file may be corrupt",
) -> np.ndarray | None:
    """Refuse non-finite rows of ``points`` read from ``path`` (``ValueError`` naming the
    file), or with ``drop`` return the mask of the finite rows after a warning through the
    ``o3d_spectral`` logger (None when all are finite)."""
    finite = np.all(np.isfinite(points), axis=1)
    bad = int(len(finite) - finite.sum())
    if not bad:
        return None
    if not drop:
        raise ValueError(
            f"{path}: {bad} of {len(finite)} {what} have NaN or infinite coordinates; "
            f"{hint}"
        )
    log.warning("%s: dropped %d of %d %s with NaN or infinite coordinates",
                path, bad, len(finite), what)
    return finite


def _umask() -> int:
    """The process's umask (read from ``/proc`` where it is shown, else set and restored:
    ``os.umask`` can only be read by setting it)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def atomic_write_text(path: str | Path, text: str) -> None:
    """Replace ``path`` by ``text`` at once: written to a temporary file in the same
    folder, then renamed over it, so a kill leaves the old file or the new, never half.
    The file gets the permissions any new file gets (0666 less the caller's umask)."""
    path = Path(path)
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        os.chmod(handle, 0o666 & ~_umask())  # mkstemp's 0600 would outlive the rename
        with os.fdopen(handle, "w") as file:
            file.write(text)
            file.flush()
            os.fsync(file.fileno())
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def _declared_points(path: Path) -> int | None:
    """The number of points a PLY or PCD file's header declares (None for other formats)."""
    suffix = path.suffix.lower()
    if suffix not in (".ply", ".pcd"):
        return None
    lines, _ = _header(path, b"end_header" if suffix == ".ply" else b"DATA")
    for line in lines:
        words = line.split()
        if suffix == ".ply" and words[:2] == ["element", "vertex"] and len(words) == 3:
            return int(words[2])
        if suffix == ".pcd" and words[:1] == ["POINTS"] and len(words) == 2:
            return int(words[1])
    return 0


def _check_written(path: Path, points: int) -> None:
    """``OSError`` unless ``path`` holds ``points`` points, all its data there."""
    try:
        check_cloud_file(path)
        declared = _declared_points(path)
        whole = (declared == points if declared is not None
                 else points == 0 or _has_lines(path, 0, points))
    except ValueError as error:
        raise OSError(f"the cloud written is incomplete ({error})") from None
    if not whole:
        raise OSError(f"the cloud written holds fewer than its {points} points")


def atomic_write_cloud(path: str | Path, points: int, write: Callable[[str], bool]) -> Path:
    """Write a cloud of ``points`` points to ``path`` whole or not at all.

    Parameters
    ----------
    path : str or Path
        The file to create or replace; its suffix chooses the format.
    points : int
        The number of points the cloud holds, checked in the file written.
    write : callable
        Writes the cloud to the path it is given (a temporary file of the same suffix, in
        the same folder) and returns whether it did (as Open3D's ``write_point_cloud``).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    OSError
        Naming ``path``, when the writer fails or the file it wrote is incomplete (a full
        disk): ``path`` is left as it was.
    """
    path = Path(path)
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.",
                                         suffix=path.suffix)
    try:
        os.chmod(handle, 0o666 & ~_umask())
        os.close(handle)
        if not write(temporary):
            raise OSError("the writer reported a failure")
        _check_written(Path(temporary), points)
        with open(temporary, "rb") as file:
            os.fsync(file.fileno())
        os.replace(temporary, path)
    except OSError as error:
        Path(temporary).unlink(missing_ok=True)
        raise OSError(f"could not write {path}: {error}; check the disk has room") from None
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
    return path
