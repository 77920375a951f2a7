"""The catalogue of the package's numeric constants: ``docs/constants.md``, written from
the code.

Every module-level numeric constant (an UPPER_CASE name bound to numbers) of
``o3d_spectral/`` lives in its layer's catalogue, a ``constants.py`` beside the modules
that use it (``o3d_spectral/search/constants.py``, ...), in a section per module that
uses it::

    # -- search.confirmation: the early stop ------------------------------------------
    # Calibrated on: what the section's constants were fitted or chosen on.
    # Measured again by: the command that re-measures them.
    # Trades: what moving them gains and costs.

    #: The constant's reason.
    MIN_FIT = 0.75

The three fields are written where the section's constants are calibrated; each constant
has its reason (the ``#:`` comment above it, shared by the constants that follow it
without a blank line). This script writes the catalogue as a page, grouped by layer and
section, with what each reason says it was measured on (the dragon scans, the turntable
pairs, the YCB-Video frames, the synthetic suites, 3DMatch, a benchmark).

    python tools/constants.py           # write docs/constants.md
    python tools/constants.py --check   # exit 1 if it is stale, a constant has no reason,
                                        # lives outside a catalogue or is bound twice in one
"""

from __future__ import annotations

import argparse
import ast
import re
import sys
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "o3d_spectral"
PAGE = ROOT / "docs" / "constants.md"
CATALOGUE = "constants.py"
#: Words of a reason that name what a constant was measured on.
SOURCES = {
    "dragon": r"\bdragon", "turntable": r"\bturntable", "YCB-Video": r"YCB-Video|\bcrop",
    "suites": r"\bsuites?\b|\bpartial\b|\boccluded\b|\bcluttered\b", "3DMatch": r"3DMatch",
    "a benchmark": r"\bbench|\bmeasured|\bmedian\b",
}
SECTION = re.compile(r"# -- (?P<title>[\w.]+: .+?) -+$")
FIELD = re.compile(r"#\s*(?P<name>Calibrated on|Measured again by|Trades):\s*(?P<text>.*)$")


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


@dataclass
class Section:
    module: str
    title: str
    fields: dict[str, str] = field(default_factory=dict)
    constants: list[Constant] = field(default_factory=list)

    @property
    def layer(self) -> str:
        return self.constants[0].layer if self.constants else ""


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


def module_constants(path: Path) -> list[Constant]:
    """The module-level numeric constants of one file."""
    source = path.read_text()
    lines = source.splitlines()
    module = ".".join(path.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__")
    return [Constant(module, node.lineno, name,
                     " ".join(ast.get_source_segment(source, value).split()),
                     _reason(lines, node.lineno))
            for node in ast.parse(source).body for name, value in _bound(node)
            if _numeric(value) and re.fullmatch(r"[A-Z][A-Z0-9_]*", name)]


def _fields(lines: list[str], start: int) -> dict[str, str]:
    """The fields under a section's title line (0-based ``start``), continuation lines
    (``#`` and an indent) joined."""
    found: dict[str, str] = {}
    name = None
    for line in lines[start + 1:]:
        stripped = line.strip()
        match = FIELD.match(stripped)
        if match:
            name = match["name"]
            found[name] = match["text"].strip()
        elif name and stripped.startswith("#  ") and not stripped.startswith("#:"):
            found[name] += " " + stripped[1:].strip()
        else:
            break
    return found


def sections() -> list[Section]:
    """Every catalogue's sections, in the package's order."""
    out = []
    for path in sorted(PACKAGE.rglob(CATALOGUE)):
        lines = path.read_text().splitlines()
        found = module_constants(path)
        module = found[0].module if found else ""
        current = None
        for row, line in enumerate(lines):
            match = SECTION.match(line.strip())
            if match:
                current = Section(module, match["title"], _fields(lines, row))
                out.append(current)
            for constant in (c for c in found if c.line == row + 1):
                if current is None:
                    current = Section(module, module)
                    out.append(current)
                current.constants.append(constant)
    return [s for s in out if s.constants]


def outside() -> list[Constant]:
    """Numeric constants that live outside a catalogue."""
    return [c for path in sorted(PACKAGE.rglob("*.py")) if path.name != CATALOGUE
            for c in module_constants(path)]


def page(found: list[Section]) -> str:
    every = [c for s in found for c in s.constants]
    calibrated = [s for s in found if "Calibrated on" in s.fields]
    out = ["# Constants", "",
           "<!-- written by tools/constants.py from the code; do not edit by hand -->", "",
           f"The package's {len(every)} numeric constants live in one catalogue per layer "
           "(`o3d_spectral/<layer>/constants.py`), a section for each module that uses "
           f"them; {len(calibrated)} sections hold calibrated constants and say what they "
           "were calibrated on, the command that measures them again and what they trade. "
           "Each constant has its reason; *measured on* names the data sets or benchmarks "
           "the reason cites. A setting a user may change is an option "
           "(`docs/usage.md`), not a constant.", ""]
    for layer in dict.fromkeys(s.layer for s in found):
        out += [f"## {layer}", ""]
        for section in (s for s in found if s.layer == layer):
            out += [f"### {section.title}", "", f"`{section.module}`", ""]
            for name, text in section.fields.items():
                shown = f"`{text}`" if name == "Measured again by" else text
                out += [f"- **{name}**: {shown}"]
            if section.fields:
                out.append("")
            out += ["| constant | value | measured on | reason |", "| --- | --- | --- | --- |"]
            for c in section.constants:
                cell = c.reason.replace("|", "\\|")
                out.append(f"| `{c.name}` | `{c.value}` | {c.measured_on} | {cell} |")
            out.append("")
    return "\n".join(out)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true",
                        help="exit 1 if docs/constants.md is stale, a reason is missing or a "
                             "constant lives outside a catalogue")
    args = parser.parse_args()
    found = sections()
    every = [c for s in found for c in s.constants]
    bare = [f"{c.module}:{c.line} {c.name}" for c in every if not c.reason]
    strays = [f"{c.module}:{c.line} {c.name}" for c in outside()]
    names = [(c.module, c.name) for c in every]  # bound twice: the later hides the earlier
    doubled = [f"{module} {name}" for module, name in sorted(set(names))
               if names.count((module, name)) > 1]
    text = page(found)
    if args.check:
        stale = not PAGE.is_file() or PAGE.read_text() != text
        for line in bare:
            print(f"no reason beside {line}")
        for line in strays:
            print(f"outside a catalogue: {line}")
        for line in doubled:
            print(f"bound twice: {line}")
        if stale:
            print(f"{PAGE.relative_to(ROOT)} is stale: run python tools/constants.py")
        return int(stale or bool(bare) or bool(strays) or bool(doubled))
    PAGE.write_text(text)
    print(f"wrote {PAGE.relative_to(ROOT)}: {len(every)} constants in {len(found)} sections, "
          f"{len(bare)} without a reason, {len(strays)} outside a catalogue")
    return 0


if __name__ == "__main__":
    sys.exit(main())
