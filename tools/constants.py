"""The catalogue of the package's numeric constants: ``docs/constants.md``, written from
the code.

Every module-level constant (an UPPER_CASE name bound to numbers) of ``o3d_spectral/``
with the reason its code gives beside it (the ``#:`` comment above it, shared by the
constants that follow it without a blank line, or a comment on its line), grouped by
layer, and what it was measured on where the reason names a data set (the dragon scans,
the turntable pairs, the YCB-Video frames, the synthetic suites, 3DMatch) or a benchmark.

    python tools/constants.py           # write docs/constants.md
    python tools/constants.py --check   # exit 1 if it is stale, or a constant has no reason
"""

from __future__ import annotations

import argparse
import ast
import re
import sys
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "o3d_spectral"
PAGE = ROOT / "docs" / "constants.md"
#: Words of a reason that name what a constant was measured on.
SOURCES = {
    "dragon": r"\bdragon", "turntable": r"\bturntable", "YCB-Video": r"YCB-Video|\bcrop",
    "suites": r"\bsuites?\b|\bpartial\b|\boccluded\b|\bcluttered\b", "3DMatch": r"3DMatch",
    "a benchmark": r"\bbench|\bmeasured|\bmedian\b",
}


@dataclass(frozen=True)
class Constant:
    module: str
    line: int
    name: str
    value: str
    reason: str

    @property
    def layer(self) -> str:
        parts = self.module.split(".")
        return parts[1] if len(parts) > 2 else "top level"

    @property
    def measured_on(self) -> str:
        return ", ".join(name for name, pattern in SOURCES.items()
                         if re.search(pattern, self.reason, re.IGNORECASE))


def _numeric(value: ast.expr) -> bool:
    nodes = list(ast.walk(value))
    numbers = [n for n in nodes if isinstance(n, ast.Constant)
               and isinstance(n.value, int | float) and not isinstance(n.value, bool)]
    texts = [n for n in nodes if isinstance(n, ast.Constant) and isinstance(n.value, str)]
    return bool(numbers) and not texts


def _bound(node: ast.stmt) -> list[tuple[str, ast.expr]]:
    """The (name, value) pairs a module-level statement binds (``A, B = 1, 2`` pairs)."""
    if isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name) and node.value:
        return [(node.target.id, node.value)]
    if not isinstance(node, ast.Assign):
        return []
    target, value = node.targets[0], node.value
    if isinstance(target, ast.Name):
        return [(target.id, value)]
    if (isinstance(target, ast.Tuple) and isinstance(value, ast.Tuple)
            and len(target.elts) == len(value.elts)):
        return [(t.id, v) for t, v in zip(target.elts, value.elts, strict=True)
                if isinstance(t, ast.Name)]
    return []


def _reason(lines: list[str], first: int) -> str:
    """The ``#:`` block above line ``first`` (1-based), climbing over the assignments
    right above it that share it; else the comment on the line itself."""
    row = first - 2
    while row >= 0 and lines[row].strip() and not lines[row].lstrip().startswith("#"):
        row -= 1  # another constant of the same block
    block = []
    while row >= 0 and lines[row].lstrip().startswith("#:"):
        block.insert(0, lines[row].lstrip()[2:].strip())
        row -= 1
    if block:
        return " ".join(block)
    _, _, comment = lines[first - 1].partition("  #")
    return comment.strip()


def constants() -> list[Constant]:
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        source = path.read_text()
        lines = source.splitlines()
        module = ".".join(path.relative_to(ROOT).with_suffix("").parts)
        for node in ast.parse(source).body:
            for name, value in _bound(node):
                if _numeric(value) and re.fullmatch(r"[A-Z][A-Z0-9_]*", name):
                    text = " ".join(ast.get_source_segment(source, value).split())
                    found.append(Constant(module.removesuffix(".__init__"), node.lineno,
                                          name, text, _reason(lines, node.lineno)))
    return found


def page(found: list[Constant]) -> str:
    measured = sum(bool(c.measured_on) for c in found)
    out = ["# Constants", "",
           "<!-- written by tools/constants.py from the code; do not edit by hand -->", "",
           f"The package's {len(found)} numeric constants, each with the reason its code "
           "gives beside it, by layer. *Measured on* names the data sets or benchmarks a "
           f"reason cites ({measured} of them): those are the calibrated ones, which a "
           "change is measured against again (`docs/benchmarks.md`). A setting a user "
           "may change is an option (`docs/usage.md`), not a constant.", ""]
    for layer in dict.fromkeys(c.layer for c in found):
        out += [f"## {layer}", "", "| constant | value | measured on | reason |",
                "| --- | --- | --- | --- |"]
        for c in (c for c in found if c.layer == layer):
            cell = c.reason.replace("|", "\\|")
            out.append(f"| `{c.module}.{c.name}` | `{c.value}` | {c.measured_on} | {cell} |")
        out.append("")
    return "\n".join(out)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true",
                        help="exit 1 if docs/constants.md is stale or a reason is missing")
    args = parser.parse_args()
    found = constants()
    bare = [f"{c.module}:{c.line} {c.name}" for c in found if not c.reason]
    text = page(found)
    if args.check:
        stale = not PAGE.is_file() or PAGE.read_text() != text
        for line in bare:
            print(f"no reason beside {line}")
        if stale:
            print(f"{PAGE.relative_to(ROOT)} is stale: run python tools/constants.py")
        return int(stale or bool(bare))
    PAGE.write_text(text)
    print(f"wrote {PAGE.relative_to(ROOT)}: {len(found)} constants, {len(bare)} without a "
          "reason")
    return 0


if __name__ == "__main__":
    sys.exit(main())
