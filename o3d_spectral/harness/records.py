"""What an evaluation run folder holds, and how it is read and written.

* ``config.json``: voxel size, seed, success thresholds, suites, methods, and one entry per
  session: start, wall time, registrations done, workers, machine, the commit of the code
  (``git rev-parse HEAD``, or null outside a checkout), the versions of o3d-spectral,
  Open3D, NumPy, SciPy, pyFFTW and Python, and the settings of every method run;
* ``results.jsonl``: one JSON object per (instance, method), appended as soon as it is
  done, so an interrupted run resumes where it stopped; a row that failed for a reason in
  the input (an empty or corrupt instance file, recorded by versions that did not stop on
  it, :func:`input_failure`) is run again on resume, and the later row wins;
* ``results.csv``: the same rows as a table (without the convergence curves), sorted by
  suite, instance and method.

``config.json`` and ``results.csv`` are replaced atomically (a temporary file renamed over
them), so a kill never leaves half a file.
"""

from __future__ import annotations

import contextlib
import importlib
import json
import os
import platform
import subprocess
from pathlib import Path

from o3d_spectral.harness._optional import require
from o3d_spectral.harness.methods import method_settings
from o3d_spectral.synthetic.manifest import atomic_write_text
from o3d_spectral.synthetic.suite import Suite

__all__ = [
    "CONFIG_FILE",
    "CURVE_COLUMNS",
    "KEY",
    "RESULTS_FILE",
    "TABLE_FILE",
    "commit",
    "done_keys",
    "input_failure",
    "load_results",
    "machine",
    "prepare_config",
    "session_record",
    "suite_name",
    "versions",
    "write_config",
    "write_results_table",
]

CONFIG_FILE = "config.json"
RESULTS_FILE = "results.jsonl"
TABLE_FILE = "results.csv"
#: Per-iteration symmetry-aware errors of iterative methods (lists; not in the CSV table).
CURVE_COLUMNS = ("curve_rotation_deg", "curve_translation_m")
#: What identifies a results row.
KEY = ("suite", "index", "method")
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
    """The name a suite has in a run: its folder's name."""
    return suite.root.resolve().name


def prepare_config(out: Path, suites: list[Suite], settings: dict, methods: list[str]) -> dict:
    """Read the run's config (checking that its settings match) or start a new one."""
    path = out / CONFIG_FILE
    if path.is_file():
        config = _read_json(path)
        if not isinstance(config, dict) or not all(
            isinstance(config.get(k), list) for k in ("suites", "methods", "sessions")
        ):
            raise ValueError(f"{path} is not a run's config (no suites, methods, sessions)")
        for key, value in settings.items():
            if config.get(key) != value:
                raise ValueError(
                    f"out {str(out)!r} holds a run with {key}={config.get(key)!r}, not "
                    f"{value!r}; resume with the same settings or choose another --out"
                )
    else:
        config = {**settings, "suites": [], "methods": [], "sessions": []}
    known = {entry["name"]: entry for entry in config["suites"]}
    for suite in suites:
        entry = known.get(suite_name(suite))
        if entry and (entry["condition"], entry["seed"]) != (
            suite.condition,
            suite.manifest["seed"],
        ):
            raise ValueError(
                f"suite {str(suite.root)!r} is {suite.condition} with seed "
                f"{suite.manifest['seed']}, but out {str(out)!r} holds results of a suite of the "
                f"same name that is {entry['condition']} with seed {entry['seed']}; choose "
                "another --out"
            )
        if entry is None:
            config["suites"].append(
                {
                    "name": suite_name(suite),
                    "path": str(suite.root.resolve()),
                    "condition": suite.condition,
                    "n": len(suite),
                    "seed": suite.manifest["seed"],
                }
            )
    config["methods"] += [m for m in methods if m not in config["methods"]]
    return config


def write_config(out: Path, config: dict) -> None:
    atomic_write_text(out / CONFIG_FILE, json.dumps(config, indent=1) + "\n")


def _read_json(path: Path) -> object:
    try:
        return json.loads(path.read_text())
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise ValueError(f"{path} is not valid JSON ({error}); move it away") from None


def _rows(file: Path, text: str) -> list[dict]:
    """The rows of ``results.jsonl`` (its ``text``); ``ValueError`` naming the file and the
    line of one that is not a row."""
    rows = []
    for number, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue
        try:
            row = json.loads(line)
        except json.JSONDecodeError:
            row = None
        if not isinstance(row, dict) or any(key not in row for key in KEY):
            raise ValueError(f"{file}, line {number}: not a results row; remove that line")
        rows.append(row)
    return rows


def input_failure(row: dict) -> bool:
    """Whether ``row`` failed because of its input (:data:`INPUT_ERRORS`)."""
    error = row.get("error")
    return isinstance(error, str) and any(part in error for part in INPUT_ERRORS)


def done_keys(results: Path) -> set[tuple]:
    """Keys of the rows already in ``results``, but for rows that failed because of their
    input (:func:`input_failure`; they will be run again, unless a later row of the same
    key succeeded); a last row cut off by a kill is removed (it will be run again)."""
    if not results.is_file():
        return set()
    text = results.read_text()
    complete = text[: text.rfind("\n") + 1]
    if complete != text:
        atomic_write_text(results, complete)
    latest = {tuple(row[k] for k in KEY): row for row in _rows(results, complete)}
    return {key for key, row in latest.items() if not input_failure(row)}


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
    """One session's entry in ``config["sessions"]``: ``counts`` (start, seconds,
    registrations, complete, workers), then the machine, commit, package versions and the
    settings of each method of ``methods``."""
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
    frame = load_results(out).drop(columns=[*CURVE_COLUMNS, "transformation"], errors="ignore")
    atomic_write_text(table, frame.to_csv(index=False))
    return table


def load_results(path: str | Path):
    """The rows of a run as a ``pandas.DataFrame``, sorted by suite, instance and method.

    Parameters
    ----------
    path : str or Path
        A run folder, or its ``results.jsonl``.
    """
    path = Path(path)
    file = path / RESULTS_FILE if path.is_dir() else path
    if not file.is_file():
        raise FileNotFoundError(f"no {RESULTS_FILE} at {path}; run o3d-spectral eval first")
    rows = _rows(file, file.read_text())  # json, not pandas' parser: floats stay exact
    if not rows:
        raise ValueError(f"{file} holds no results yet")
    frame = require("pandas").DataFrame(rows)
    frame = frame.drop_duplicates(subset=list(KEY), keep="last")
    return frame.sort_values(list(KEY)).reset_index(drop=True)
