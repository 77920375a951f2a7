"""One run at a time in an output folder: ``eval``, ``reconstruct`` and ``make-suite``
claim their folder for as long as they run.

A run's claim is a small file in ``<folder>/.o3d-spectral-runs/`` naming its command,
process id and host, held under an advisory lock (POSIX ``flock``) from the moment it is
written until the run ends, however it ends: the operating system drops the lock of a
process that is gone, so a claim whose lock can be taken is stale, and is taken over
with a note. Claims are read and written inside a short critical section, under the lock
of ``<folder>/.o3d-spectral.lock``, so two runs started at the same instant cannot both
see a free folder. Nothing of either is left once the last run ends.

Runs that may share a folder say so with the same ``group`` and distinct ``part``s: the
shards ``i/n`` of one evaluation with the same settings. Any other run finds the folder
busy: :class:`FolderBusyError`, one line naming the folder and the other run's process.
Platforms without ``flock`` (Windows) run unguarded.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import socket
from collections.abc import Iterator
from pathlib import Path

try:
    import fcntl
except ImportError:  # Windows: no advisory locks of this kind
    fcntl = None

__all__ = ["CLAIMS", "LOCK", "FolderBusyError", "folder_lock", "foreign_entries"]

log = logging.getLogger(__name__)

#: The critical section's lock file and the claims' folder, inside the output folder.
LOCK, CLAIMS = ".o3d-spectral.lock", ".o3d-spectral-runs"


class FolderBusyError(OSError):
    """The output folder is claimed by another run that is still going."""


def foreign_entries(folder: Path) -> list[Path]:
    """The entries of ``folder`` other than the lock's own files (for a command that
    wants an empty folder)."""
    return [path for path in folder.iterdir() if path.name not in (LOCK, CLAIMS)]


@contextlib.contextmanager
def folder_lock(folder: str | Path, command: str, *, group: str | None = None,
                part: str | None = None) -> Iterator[None]:
    """Claim ``folder`` (created if missing) for ``command`` while the block runs.

    Parameters
    ----------
    folder : str or Path
        The run's output folder.
    command : str
        What the run is, for the message another run shows (``"o3d-spectral eval"``).
    group, part : str, optional
        Runs of one ``group`` with distinct ``part``s share the folder (the shards of one
        evaluation); without a group a run has the folder to itself.

    Raises
    ------
    FolderBusyError
        While another run holds a claim it cannot share: one line naming ``folder``, the
        other run's command and process id.

    Notes
    -----
    A folder the call created is removed again if the run left it empty.
    """
    folder = Path(folder)
    created = not folder.exists()
    folder.mkdir(parents=True, exist_ok=True)
    try:
        if fcntl is None:
            yield
        else:
            with _claimed(folder, command, group, part):
                yield
    finally:
        if created:  # a run that wrote nothing leaves no empty folder behind
            with contextlib.suppress(OSError):
                folder.rmdir()


@contextlib.contextmanager
def _claimed(folder: Path, command: str, group: str | None, part: str | None
             ) -> Iterator[None]:
    """The claim of :func:`folder_lock`, held while the block runs."""
    mine = {"command": command, "pid": os.getpid(), "host": socket.gethostname(),
            "group": group, "part": part}
    with _critical(folder):
        for other in _live_claims(folder):
            if group is None or other.get("group") != group or other.get("part") == part:
                raise FolderBusyError(_busy(folder, other))
        claim, handle = _write_claim(folder / CLAIMS, mine)
    try:
        yield
    finally:
        with _critical(folder):
            claim.unlink(missing_ok=True)
            os.close(handle)
            with contextlib.suppress(OSError):  # another run's claim is still there
                (folder / CLAIMS).rmdir()


def _busy(folder: Path, other: dict) -> str:
    host = "" if other.get("host") == socket.gethostname() else f" on {other.get('host')}"
    return (f"{folder} is in use by another run: {other.get('command')} (process "
            f"{other.get('pid')}{host}); wait for it to end or choose another folder")


@contextlib.contextmanager
def _critical(folder: Path) -> Iterator[None]:
    """Hold the lock of ``folder/LOCK`` (waiting for it: it is held for milliseconds),
    and remove the file on the way out when no claim is left."""
    path = folder / LOCK
    while True:
        handle = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            same = os.fstat(handle).st_ino == os.stat(path).st_ino
        except FileNotFoundError:  # removed by the run that held it just before
            same = False
        if same:
            break
        os.close(handle)
    try:
        yield
    finally:
        if not (folder / CLAIMS).exists():
            path.unlink(missing_ok=True)  # while held: a waiting run sees it gone, retries
        os.close(handle)


def _live_claims(folder: Path) -> Iterator[dict]:
    """The claims of runs still going; a stale one (its process gone, its lock free) is
    removed with a warning."""
    for path in sorted((folder / CLAIMS).glob("*.json")):
        handle = os.open(path, os.O_RDWR)
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:  # held: its run is going
            yield _read(path)
            continue
        finally:
            os.close(handle)
        other = _read(path)
        path.unlink(missing_ok=True)
        log.warning("%s: took over the claim of %s (process %s), which ended without "
                    "releasing it", folder, other.get("command"), other.get("pid"))


def _read(path: Path) -> dict:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):  # written by an older or foreign program
        return {}


def _write_claim(claims: Path, mine: dict) -> tuple[Path, int]:
    """A new claim file in ``claims`` holding ``mine``, locked: (its path, the open
    descriptor that holds the lock until the run closes it)."""
    claims.mkdir(exist_ok=True)
    path = claims / f"{mine['pid']}-{os.urandom(4).hex()}.json"
    handle = os.open(path, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o644)
    fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    os.write(handle, json.dumps(mine).encode())
    return path, handle
