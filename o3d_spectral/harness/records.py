"""What an evaluation run folder holds, and how it is read and written.

Several sessions may write one run folder at once (shards on several machines, a second
``eval`` adding methods), so no file is written by two of them:

* ``sessions/ID.json``: one file per session (``ID``: start time, host, process, a random
  token), written when it starts and rewritten when it ends: the run's settings (voxel
  size, seed, success thresholds), its suites and methods, and the session's own record:
  start, wall time, registrations done, executor and workers, shard and instance
  selection, machine, the commit of the code (``git rev-parse HEAD``, or null outside a
  checkout), the versions of o3d-spectral, Open3D, NumPy, SciPy, pyFFTW and Python, and
  the settings of every method run;
* ``results/ID.jsonl``: the session's rows, one JSON object per (instance, method),
  appended (one ``write`` per row, ``O_APPEND``) as soon as it is done, so an interrupted
  run resumes where it stopped;
* ``results.csv``: every session's rows as a table (without the convergence curves),
  sorted by suite, instance and method.

:func:`read_config` merges the sessions' files and :func:`load_results` their rows. Run
folders written before sessions had their own files (``config.json`` and one
``results.jsonl``) are read the same way, and resumed into the new layout. Where two files
hold a row of the same (instance, method), the later file's row wins (files sort by the
session's start). A row that failed for a reason in the input (an empty or corrupt instance
file, recorded by versions that did not stop on it, :func:`input_failure`) is run again on
resume, and the new row wins. A session or results file that is not what it should be (not
JSON, a line that is not a row) is an error naming the file (and the line).

Files that are rewritten (a session's record, ``results.csv``) are written to a temporary
file in the same folder and moved over the old one (:func:`atomic_write_text`), so a reader
never sees half a file.
"""

from __future__ import annotations

import contextlib
import datetime
import hashlib
import importlib
import json
import os
import platform
import secrets
import socket
import subprocess
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

from o3d_spectral.harness._optional import parse_json, require
from o3d_spectral.harness.row_checks import check_row
from o3d_spectral.io.files import atomic_write_text

if TYPE_CHECKING:
    from o3d_spectral.synthetic.suite import Suite

__all__ = [
    "CONFIG_FILE",
    "CURVE_COLUMNS",
    "KEY",
    "RESULTS_DIR",
    "RESULTS_FILE",
    "SESSIONS_DIR",
    "TABLE_FILE",
    "append_row",
    "atomic_write_text",
    "commit",
    "done_keys",
    "input_failure",
    "load_results",
    "machine",
    "new_session_id",
    "open_results",
    "prepare_session",
    "read_config",
    "result_files",
    "session_record",
    "suite_name",
    "versions",
    "write_results_table",
    "write_session",
]

CONFIG_FILE = "config.json"  # runs before per-session files (read only)
RESULTS_FILE = "results.jsonl"  # runs before per-session files (read only)
SESSIONS_DIR = "sessions"
RESULTS_DIR = "results"
TABLE_FILE = "results.csv"
#: Per-iteration symmetry-aware errors of iterative methods (lists; not in the CSV table).
CURVE_COLUMNS = ("curve_rotation_deg", "curve_translation_m")
#: What identifies a results row.
KEY = ("suite", "index", "method")
#: The settings every session of a run must share.
SETTINGS = ("voxel_size", "seed", "criteria")
#: Parts of the error of a row that failed because of its input, not of its method: an
#: instance file that was missing or corrupt (read as an empty or garbage cloud).
INPUT_ERRORS = (
    "source is empty", "target is empty", "NaN or infinite", "no such file",
    "missing instance file", "truncated or corrupt", "Open3D read no points",
    "has no 'positions'",
)
#: Version of each package, by the key it has in a session's ``versions``.
_PACKAGES = {
    "o3d_spectral": "o3d_spectral",
    "open3d": "open3d",
    "numpy": "numpy",
    "scipy": "scipy",
    "pyfftw": "pyfftw",
}


def suite_name(suite: Suite) -> str:
    """The name a suite has in a run: its folder's name (or the ``name`` of a benchmark's
    instance set, :class:`~o3d_spectral.harness.bop.BopSet`,
    :class:`~o3d_spectral.harness.pairs.PairSet`)."""
    return getattr(suite, "name", None) or suite.root.resolve().name


def new_session_id() -> str:
    """A name no other session has, sorting by start time:
    ``20260101T120000123456-host-pid-token`` (microseconds, so a session started within
    the same second as the one before still sorts after it)."""
    now = datetime.datetime.now().strftime("%Y%m%dT%H%M%S%f")
    host = "".join(c if c.isalnum() else "-" for c in socket.gethostname())[:32]
    return f"{now}-{host}-{os.getpid()}-{secrets.token_hex(3)}"


def _read_json(path: Path) -> object:
    try:
        return json.loads(path.read_text())
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise ValueError(f"{path} is not valid JSON ({error}); move it away") from None


def _config_documents(out: Path) -> list[dict]:
    """The run's settings documents: an older run's ``config.json``, then every session's
    file, each with its ``sessions``; ``ValueError`` naming a file that is not one."""
    documents = []
    legacy = out / CONFIG_FILE
    if legacy.is_file():
        document = _read_json(legacy)
        if not isinstance(document, dict) or not all(
            isinstance(document.get(k), list) for k in ("suites", "methods", "sessions")
        ):
            raise ValueError(f"{legacy} is not a run's config (no suites, methods, sessions)")
        documents.append(document)
    for path in sorted((out / SESSIONS_DIR).glob("*.json")):
        document = _read_json(path)
        if not isinstance(document, dict) or not isinstance(document.get("session"), dict):
            raise ValueError(f"{path} is not a session's file (no session record)")
        documents.append(document | {"sessions": [document["session"]]})
    return documents


def read_config(out: str | Path) -> dict:
    """The run's settings, suites, methods and sessions, merged from every session's file
    (and a ``config.json`` of an older run); ``{}`` for a folder without any.

    Sessions are sorted by start; suites and methods are listed in the order sessions first
    named them.
    """
    documents = _config_documents(Path(out))
    if not documents:
        return {}
    config = {key: documents[0].get(key) for key in SETTINGS}
    config |= {"suites": [], "methods": [], "sessions": []}
    for document in documents:
        known = {entry["name"] for entry in config["suites"]}
        config["suites"] += [s for s in document.get("suites", []) if s["name"] not in known]
        config["methods"] += [m for m in document.get("methods", []) if m not in config["methods"]]
        config["sessions"] += document.get("sessions", [])
    config["sessions"].sort(key=lambda s: (s.get("started") or "", s.get("id") or ""))
    return config


def _suite_entry(suite: Suite) -> dict:
    return {
        "name": suite_name(suite),
        "path": str(suite.root.resolve()),
        "condition": suite.condition,
        "n": len(suite),
        "seed": suite.manifest["seed"],
        # a suite rebuilt in place with the same seed but other instances has another
        "manifest_sha256": hashlib.sha256(
            json.dumps(suite.manifest, sort_keys=True, default=str).encode()).hexdigest(),
    }


def prepare_session(out: Path, suites: list[Suite], settings: dict, methods: list[str]) -> dict:
    """Check a new session against the run in ``out`` (same settings; a suite of a known
    name is the same suite); the session's entry: ``settings``, its suites and methods."""
    config = read_config(out)
    for key, value in settings.items():
        if config and config.get(key) != value:
            raise ValueError(
                f"out {str(out)!r} holds a run with {key}={config.get(key)!r}, not "
                f"{value!r}; resume with the same settings or choose another --out"
            )
    known = {entry["name"]: entry for entry in config.get("suites", [])}
    for suite in suites:
        entry, new = known.get(suite_name(suite)), _suite_entry(suite)
        if entry and (entry["condition"], entry["seed"]) != (new["condition"], new["seed"]):
            raise ValueError(
                f"suite {str(suite.root)!r} is {suite.condition} with seed "
                f"{suite.manifest['seed']}, but out {str(out)!r} holds results of a suite of the "
                f"same name that is {entry['condition']} with seed {entry['seed']}; choose "
                "another --out"
            )
        if entry and entry.get("manifest_sha256", new["manifest_sha256"]) != new["manifest_sha256"]:
            raise ValueError(
                f"suite {str(suite.root)!r} is not the suite out {str(out)!r} holds results "
                "of: its manifest changed (it was rebuilt in place); choose another --out")
    return {**settings, "suites": [_suite_entry(s) for s in suites], "methods": list(methods)}


def write_session(out: Path, entry: dict, record: dict) -> Path:
    """Write (or rewrite) the session file of ``record["id"]``: ``entry`` (from
    :func:`prepare_session`) and the session's ``record``."""
    folder = out / SESSIONS_DIR
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{record['id']}.json"
    atomic_write_text(path, json.dumps(entry | {"session": record}, indent=1) + "\n")
    return path


def result_files(path: str | Path) -> list[Path]:
    """The files holding a run's rows, oldest first: an older run's ``results.jsonl``, then
    every session's file by start (``path`` may also be one file)."""
    path = Path(path)
    if not path.is_dir():
        return [path] if path.is_file() else []
    legacy = [path / RESULTS_FILE] if (path / RESULTS_FILE).is_file() else []
    return legacy + sorted((path / RESULTS_DIR).glob("*.jsonl"))


def _rows(file: Path) -> list[dict]:
    """The complete rows of a results file: a last line without its newline (a session
    killed mid-write, or one still writing) is left out; ``ValueError`` naming the file and
    the line of one that is not a row."""
    text = file.read_text()
    rows = []
    for number, line in enumerate(text[: text.rfind("\n") + 1].splitlines(), 1):
        if not line.strip():
            continue
        rows.append(check_row(parse_json(line), f"{file}, line {number}"))
    return rows


def input_failure(row: dict) -> bool:
    """Whether ``row`` failed because of its input (:data:`INPUT_ERRORS`)."""
    error = row.get("error")
    return isinstance(error, str) and any(part in error for part in INPUT_ERRORS)


def done_keys(out: Path) -> set[tuple]:
    """Keys of the rows already in the run folder ``out``, but for those whose latest row
    (over every session's file) failed because of its input (:func:`input_failure`): they
    will be run again."""
    latest = {tuple(row[k] for k in KEY): row for file in result_files(out) for row in _rows(file)}
    return {key for key, row in latest.items() if not input_failure(row)}


@contextlib.contextmanager
def open_results(out: Path, session: str) -> Iterator[int]:
    """The session's results file, opened for appending (a file descriptor for
    :func:`append_row`)."""
    folder = out / RESULTS_DIR
    folder.mkdir(parents=True, exist_ok=True)
    descriptor = os.open(folder / f"{session}.jsonl", os.O_WRONLY | os.O_CREAT | os.O_APPEND,
                         0o666)  # less the caller's umask
    try:
        yield descriptor
    finally:
        os.close(descriptor)


def append_row(descriptor: int, row: dict) -> None:
    """Append one row as one line, in a single ``write`` (a reader sees all of it or none;
    a partial line left by a kill is skipped on reading)."""
    line = (json.dumps(row) + "\n").encode()
    written = os.write(descriptor, line)
    while written < len(line):  # a short write (a full disk, a signal): finish the line
        written += os.write(descriptor, line[written:])


def machine() -> dict:
    """The computer: CPU, cores, memory (GiB) and platform."""
    cpu = platform.processor()
    with contextlib.suppress(OSError):
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    memory = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30
    return {
        "cpu": cpu,
        "cores": os.cpu_count(),
        "memory_gib": round(memory, 1),
        "platform": platform.platform(),
    }


def versions() -> dict:
    """Versions of the packages a registration depends on, and of Python (None for a
    package that is not installed)."""
    found: dict[str, str | None] = {}
    for key, module in _PACKAGES.items():
        try:
            found[key] = str(importlib.import_module(module).__version__)
        except (ImportError, AttributeError):
            found[key] = None
    return found | {"python": platform.python_version()}


def _git(*args: str) -> str | None:
    """Output of ``git ARGS`` in the imported package's folder; None if it fails."""
    import o3d_spectral

    try:
        done = subprocess.run(
            ["git", *args],
            cwd=Path(o3d_spectral.__file__).resolve().parent,
            capture_output=True,
            text=True,
            timeout=10,
            check=True,
        )
    except (OSError, subprocess.SubprocessError):
        return None
    return done.stdout.strip() or None


def commit() -> str | None:
    """``git rev-parse HEAD`` of the checkout holding the imported package; None when git
    is missing or the package's files are not tracked there (an installed copy)."""
    if _git("ls-files", "--error-unmatch", "__init__.py") is None:
        return None
    return _git("rev-parse", "HEAD")


def session_record(methods: list[str], **counts) -> dict:
    """One session's record: ``counts`` (id, start, seconds, registrations, complete,
    executor, workers, ...), then the machine, commit, package versions and the settings
    of each method of ``methods``."""
    from o3d_spectral.harness.methods import method_settings  # Open3D: not for reports

    return {
        **counts,
        "machine": machine(),
        "commit": commit(),
        "versions": versions(),
        "method_settings": {name: method_settings(name) for name in methods},
    }


def write_results_table(out: Path) -> Path:
    """Write ``results.csv`` (the rows without curves and transformations) and return it."""
    table = out / TABLE_FILE
    if not any(_rows(file) for file in result_files(out)):  # a shard with nothing to run
        atomic_write_text(table, "")
        return table
    frame = load_results(out).drop(columns=[*CURVE_COLUMNS, "transformation"], errors="ignore")
    atomic_write_text(table, frame.to_csv(index=False))
    return table


#: Row columns only some methods fill (None for the others): read as floats, so that a
#: selection of rows has the same dtype whichever methods it holds.
FLOAT_COLUMNS = frozenset({"confidence"})


def load_results(path: str | Path):
    """The rows of a run as a ``pandas.DataFrame``, sorted by suite, instance and method
    (a pair done twice, by concurrent sessions, once: the later session's row).

    Parameters
    ----------
    path : str or Path
        A run folder (every session's rows), or one results file (``.jsonl``).
    """
    path = Path(path)
    files = result_files(path)
    if not files:
        raise FileNotFoundError(f"no results at {path}; run o3d-spectral eval first")
    rows = [row for file in files for row in _rows(file)]  # json: floats stay exact
    if not rows:
        raise ValueError(f"{path} holds no results yet")
    pandas = require("pandas")
    frame = pandas.DataFrame(rows)
    for column in FLOAT_COLUMNS & set(frame.columns):  # NaN where a method has none
        frame[column] = pandas.to_numeric(frame[column]).astype(float)
    frame = frame.drop_duplicates(subset=list(KEY), keep="last")
    frame = frame.sort_values(list(KEY)).reset_index(drop=True)
    config = read_config(path if path.is_dir() else path.parent)
    frame.attrs["methods"] = config.get("methods", [])  # the run's order, for the tables
    return frame
