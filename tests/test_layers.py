"""Imports point one way, and no module reaches into another's private names.

The layers, lowest first: the core (the method and its maths), ``synthetic`` (the scene
generator and the models' symmetries), then ``harness`` (evaluation) and ``servo`` (visual
servoing), which do not use each other, and ``cli`` over all of them. A module may import
from its own layer and the layers below it.

Within the core, its parts in the same way, lowest first (:data:`CORE_ORDER`): ``common``
(checks, optional libraries, threads), ``io`` (clouds as given), ``spectra`` (the pure
maths), ``correlation`` (the batched phase correlation, free of Open3D), the user's
settings (``options``), ``law`` (the paper's control law on voxel grids),
``refinement`` (the polish), ``evidence`` (what the data say about a pose), ``search``,
the calls (the package's other top-level modules: one registration from its clouds to
its result), ``voxel`` (the voxel size, chosen by trial with the calls) and ``multiway``.
A part imports itself and the parts below it; ``correlation`` not ``io``, so that it runs
where Open3D is not installed. Read from the source with ``ast``: nothing is imported.

A private name (one starting with an underscore, not a dunder) is its module's own: no
other module, script or test imports it or reads it as an attribute.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from functools import cache
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "o3d_spectral"
#: Each outer layer and the layers it may import (besides its own).
ALLOWED = {
    "core": set(),
    "synthetic": {"core"},
    "harness": {"core", "synthetic"},
    "servo": {"core", "synthetic"},
    "cli": {"core", "synthetic", "harness", "servo"},
}


#: The core's parts, lowest first: each imports only itself and the parts before it.
CORE_ORDER = ("common", "io", "spectra", "correlation", "options", "law", "refinement",
              "evidence", "search", "calls", "voxel", "multiway")
#: Parts below a part that it still does not import.
CORE_APART = {"correlation": {"io"}}


def module_name(path: Path) -> str:
    """The dotted name of a source file under the project root."""
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def layer(module: str) -> str:
    """The layer of a module of the package (see the module docstring)."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 and parts[1] in ALLOWED else "core"


def core_part(module: str) -> str:
    """The part of the core a module of it belongs to (:data:`CORE_ORDER`): its folder,
    ``options``, or ``calls`` for the package's other top-level modules."""
    parts = module.split(".")
    if len(parts) > 1 and parts[1] in CORE_ORDER:
        return parts[1]
    return "calls"


def is_module(dotted: str) -> bool:
    """Whether ``dotted`` names a module or package of the project."""
    return _is_module(ROOT.joinpath(*dotted.split(".")))


@cache
def _is_module(path: Path) -> bool:
    return path.with_suffix(".py").is_file() or (path / "__init__.py").is_file()


@cache
def parsed(path: Path) -> ast.Module:
    """A file's syntax tree, parsed once."""
    return ast.parse(path.read_text(), str(path))


def imported(path: Path) -> Iterator[tuple[ast.AST, str, str | None]]:
    """``(node, module, name)`` for every import in a file: ``name`` is what a ``from``
    import takes from ``module`` (None for ``import module``); relative imports resolved."""
    here = module_name(path)
    package = here if path.name == "__init__.py" else here.rpartition(".")[0]
    for node in ast.walk(parsed(path)):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield node, alias.name, None
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, *([base] if base else [])])
            for alias in node.names:
                yield node, base, alias.name


def package_imports(path: Path) -> Iterator[str]:
    """The package's modules a file imports (``from a import b``: ``a.b`` when ``b`` is a
    module, else ``a``)."""
    for _, module, name in imported(path):
        if name is not None and is_module(f"{module}.{name}"):
            module = f"{module}.{name}"
        if module.split(".")[0] == "o3d_spectral":
            yield module


def private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def module_aliases(path: Path) -> dict[str, str]:
    """Local names a file binds to the project's modules, and the module each names."""
    aliases = {}
    for node, module, name in imported(path):
        if name is None:
            top = module.split(".")[0]
            bound = next(a for a in node.names if a.name == module)
            aliases[bound.asname or top] = module if bound.asname else top
        elif is_module(f"{module}.{name}"):
            bound = next(a for a in node.names if a.name == name)
            aliases[bound.asname or name] = f"{module}.{name}"
    return {local: module for local, module in aliases.items() if is_module(module)}


def dotted(node: ast.AST) -> str | None:
    """``a.b.c`` for a chain of attributes on a name, else None."""
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        head = dotted(node.value)
        return None if head is None else f"{head}.{node.attr}"
    return None


def private_reaches(path: Path) -> Iterator[str]:
    """Where a file takes another module's private name: ``from m import _x``,
    ``m._x`` on a module ``m`` of the project, and ``setattr`` / ``getattr`` /
    ``monkeypatch.setattr`` of ``(m, "_x")``."""
    where = path.relative_to(ROOT)
    for node, module, name in imported(path):
        if name is not None and private(name) and not is_module(f"{module}.{name}"):
            yield f"{where}:{node.lineno}: from {module} import {name}"
    aliases = module_aliases(path)

    def resolved(expression: ast.AST) -> str | None:
        chain = dotted(expression)
        if chain is None or chain.split(".")[0] not in aliases:
            return None
        head, _, rest = chain.partition(".")
        full = aliases[head] + (f".{rest}" if rest else "")
        return full if is_module(full) else None

    for node in ast.walk(parsed(path)):
        if isinstance(node, ast.Attribute) and private(node.attr):
            owner = resolved(node.value)
            if owner is not None and not is_module(f"{owner}.{node.attr}"):
                yield f"{where}:{node.lineno}: {owner}.{node.attr}"
        elif isinstance(node, ast.Call) and len(node.args) >= 2:
            func = dotted(node.func) or ""
            name = node.args[1]
            if (
                func.split(".")[-1] in ("setattr", "getattr", "delattr")
                and isinstance(name, ast.Constant)
                and isinstance(name.value, str)
                and private(name.value)
                and resolved(node.args[0]) is not None
            ):
                yield f"{where}:{node.lineno}: {func}({resolved(node.args[0])}, {name.value!r})"


PACKAGE_FILES = sorted(PACKAGE.rglob("*.py"))
CHECKED_FILES = sorted(
    [*PACKAGE_FILES, *(ROOT / "eval").rglob("*.py"), *(ROOT / "tests").rglob("*.py"),
     *(ROOT / "examples").rglob("*.py")]
)


@pytest.mark.parametrize("path", PACKAGE_FILES, ids=lambda p: str(p.relative_to(PACKAGE)))
def test_imports_point_down_the_layers(path):
    own = layer(module_name(path))
    wrong = sorted(
        {
            target
            for target in package_imports(path)
            if layer(target) != own and layer(target) not in ALLOWED[own]
        }
    )
    assert not wrong, f"the {own} layer imports {wrong}"
    if own != "core" or path == PACKAGE / "__init__.py":
        return
    part = core_part(module_name(path))
    below = set(CORE_ORDER[: CORE_ORDER.index(part) + 1]) - CORE_APART.get(part, set())
    wrong = sorted({target for target in package_imports(path)
                    if layer(target) == "core" and core_part(target) not in below})
    assert not wrong, f"o3d_spectral's {part} imports {wrong}"


def test_no_private_name_is_reached_from_another_module():
    reaches = [line for path in CHECKED_FILES for line in private_reaches(path)]
    assert not reaches, "private names used outside their module:\n" + "\n".join(reaches)


def test_the_checks_see_what_they_forbid(tmp_path, monkeypatch):
    """The two checks find a forbidden direction and each form of private reach."""
    monkeypatch.setattr("tests.test_layers.ROOT", tmp_path)
    package = tmp_path / "o3d_spectral"
    (package / "harness").mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (package / "harness" / "__init__.py").write_text("")
    (package / "harness" / "errors.py").write_text("def _helper(): ...\n")
    core = package / "plots.py"
    core.write_text(
        "from .harness.errors import _helper\n"
        "from .harness import errors\n"
        "import o3d_spectral.harness.errors as e\n"
        "errors._helper()\n"
        "e._helper()\n"
        "setattr(errors, '_helper', None)\n"
        "from . import harness\n"  # a module: no private name reached
    )
    assert layer(module_name(core)) == "core"
    assert {layer(target) for target in package_imports(core)} == {"harness"}
    assert core_part("o3d_spectral.spectra.so3") == "spectra"
    assert core_part("o3d_spectral.common.checks") == "common"
    assert core_part("o3d_spectral.law.loop") == "law"
    assert core_part("o3d_spectral.run") == "calls"
    assert CORE_ORDER.index("spectra") < CORE_ORDER.index("law")  # the maths never use the law
    assert core_part("o3d_spectral.correlation.batched") == "correlation"
    reaches = list(private_reaches(core))
    assert len(reaches) == 4, reaches
