"""Probes of the command line as a careless script or an impatient user meets it: signals
at any moment, two runs into one folder, closed and broken standard streams.

Each probe starts ``o3d-spectral`` in a fresh process and checks what it left: the exit
status, the lines on stderr (one, or none; never a traceback) and the output folder.

* **signals**: SIGINT and SIGTERM sent to ``register``, ``make-suite``, ``convert``,
  ``reconstruct`` and ``eval`` after each of ``--moments`` seconds: status 130 / 143 and
  one line, or 0 when the command had finished; before the interpreter reaches the
  program's first instruction (its first ~0.05 s) and in the interpreter's exit after
  the results are written, the system's default applies, which the lines say;
* **folders**: two evals into one folder started together (same settings; other voxel
  sizes): one refused on one line naming the other's process, one clean run, each row
  once; the shards 0/2 and 1/2 of one run together: both clean;
* **streams**: ``--version``, ``--help`` and ``register --json`` into a pipe its reader
  closed (status 141, nothing on stderr) and with the standard output closed (status 1,
  one line).

Usage::

    python eval/fuzz_cli.py [--moments 0.1 0.3 1 3] [--probes streams folders signals]
        [--commands register make-suite convert reconstruct eval] [--out /tmp/fuzz]

Prints one line a probe and exits 1 if any failed.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

DRAGON = Path(__file__).resolve().parents[1] / "o3d_spectral" / "datasets" / "real" / "dragon"
SCANS = [str(DRAGON / f"dragonStandRight_{a}.ply") for a in (0, 24, 48)]
PROGRAM = [sys.executable, "-c", "from o3d_spectral.cli import program; program()"]


def _start(argv: list[str], **kwargs) -> subprocess.Popen:
    return subprocess.Popen([*PROGRAM, *argv], stdout=kwargs.pop("stdout", subprocess.PIPE),
                            stderr=subprocess.PIPE, text=True, **kwargs)


def _lines(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if line.strip() and ": WARNING: " not in line]


def _commands(out: Path) -> dict[str, list[str]]:
    return {
        "register": [*SCANS[:2], "--voxel-size", "0.005", "--json"],
        "make-suite": ["full", "--n", "60", "--out", str(out / "suite")],
        "convert": ["dragon", str(out / "converted")],
        "reconstruct": [*SCANS, "--voxel-size", "0.006", "--out", str(out / "model")],
        "eval": ["--suite", str(out / "base"), "--methods", "spectral_global", "--out",
                 str(out / "run")],
    }


def signal_probes(out: Path, moments: list[float], commands: list[str]
                  ) -> list[tuple[str, bool, str]]:
    results = []
    for name, argv in _commands(out).items():
        if name not in commands:
            continue
        for number in (signal.SIGINT, signal.SIGTERM):
            word, status = {signal.SIGINT: ("interrupted", 130),
                            signal.SIGTERM: ("terminated", 143)}[number]
            for moment in moments:
                for folder in ("suite", "converted", "model", "run"):
                    shutil.rmtree(out / folder, ignore_errors=True)
                run = _start([name, *argv])
                time.sleep(moment)
                run.send_signal(number)
                stdout, stderr = run.communicate(timeout=600)
                lines = _lines(stderr)
                if run.returncode == -number and stdout:  # the default handler, at exit
                    verdict, ok = "finished, stopped in the interpreter's exit", True
                elif run.returncode == -number:  # the default handler, before the program's
                    verdict, ok = "before the program", True
                elif run.returncode == 0:
                    verdict, ok = "finished first", "Traceback" not in stderr
                else:
                    verdict = f"status {run.returncode}, {len(lines)} line(s)"
                    ok = (run.returncode == status and len(lines) == 1
                          and f": {word}" in lines[0] and "Traceback" not in stderr)
                results.append((f"{name} {number.name} at {moment:g} s", ok, verdict))
    return results


def folder_probes(out: Path) -> list[tuple[str, bool, str]]:
    results = []
    for label, extras in (("same settings", [[], []]),
                          ("voxel 8 / 12 mm", [["--voxel-size", "0.008"],
                                               ["--voxel-size", "0.012"]]),
                          ("shards 0/2 + 1/2", [["--shard", "0/2"], ["--shard", "1/2"]])):
        shutil.rmtree(out / "run", ignore_errors=True)
        base = ["eval", "--suite", str(out / "base"), "--methods", "spectral_global",
                "--out", str(out / "run")]
        runs = [_start([*base, *extra]) for extra in extras]
        stderrs = [run.communicate(timeout=600)[1] for run in runs]
        codes = sorted(run.returncode for run in runs)
        rows = [json.loads(line) for path in (out / "run" / "results").glob("*.jsonl")
                for line in path.read_text().splitlines()]
        keys = [(row["suite"], row["index"], row["method"]) for row in rows]
        once = len(keys) == len(set(keys))
        if label.startswith("shards"):
            ok = codes == [0, 0] and once and len(keys) == 2  # two instances, one method
        else:
            refused = [_lines(s) for s in stderrs if "in use by another run" in s]
            ok = codes == [0, 1] and once and len(refused) == 1 and len(refused[0]) == 1
        results.append((f"two evals into one folder, {label}", ok,
                        f"statuses {codes}, {len(keys)} rows, each once: {once}"))
    return results


def stream_probes() -> list[tuple[str, bool, str]]:
    results = []
    for argv in (["--version"], ["--help"], ["register", *SCANS[:2], "--voxel-size", "0.005",
                                             "--json"]):
        run = _start(argv)
        run.stdout.close()
        _, stderr = run.communicate(timeout=600)
        ok = run.returncode == 141 and not _lines(stderr)
        results.append((f"{' '.join(argv[:1])} into a closed pipe", ok,
                        f"status {run.returncode}, {len(_lines(stderr))} line(s)"))
    run = _start(["--version"], stdout=subprocess.DEVNULL, preexec_fn=lambda: os.close(1))
    _, stderr = run.communicate(timeout=60)
    ok = run.returncode == 1 and len(_lines(stderr)) == 1
    results.append(("--version with stdout closed", ok,
                    f"status {run.returncode}, {len(_lines(stderr))} line(s)"))
    return results


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--moments", type=float, nargs="+", default=[0.1, 0.3, 0.6, 1.0, 3.0],
                        help="seconds after the start at which each signal is sent")
    parser.add_argument("--commands", nargs="+", default=list(_commands(Path())),
                        help="the commands the signal probes stop (default all)")
    parser.add_argument("--probes", nargs="+", default=["streams", "folders", "signals"],
                        choices=["streams", "folders", "signals"])
    parser.add_argument("--out", type=Path, default=Path("/tmp/o3d_spectral_fuzz"))
    args = parser.parse_args()
    shutil.rmtree(args.out, ignore_errors=True)
    args.out.mkdir(parents=True)
    subprocess.run([*PROGRAM, "make-suite", "full", "--n", "2", "--out",
                    str(args.out / "base")], check=True, capture_output=True)
    results = ([*stream_probes()] if "streams" in args.probes else []) + (
        folder_probes(args.out) if "folders" in args.probes else []) + (
        signal_probes(args.out, args.moments, args.commands) if "signals" in args.probes
        else [])
    for probe, ok, verdict in results:
        print(f"{'ok  ' if ok else 'FAIL'} {probe}: {verdict}")
    failed = sum(not ok for _, ok, _ in results)
    early = sum(verdict == "before the program" for _, _, verdict in results)
    print(f"{len(results) - failed} of {len(results)} probes held ({early} stopped before the "
          "program's first instruction, by the system's default action)")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
