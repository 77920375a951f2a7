"""The package stays readable in one pass: small modules, short functions.

Function length counts code lines, not the docstring: a docstring that teaches is welcome.
"""

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "o3d_spectral"
MODULES = sorted(PACKAGE.rglob("*.py"))
MAX_MODULE_LINES = 400
MAX_FUNCTION_LINES = 60


def _code_lines(node: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    length = node.end_lineno - node.lineno + 1
    first = node.body[0]
    if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) and isinstance(
        first.value.value, str
    ):
        length -= first.end_lineno - first.lineno + 1
    return length


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(PACKAGE)))
def test_modules_and_functions_are_short(path):
    text = path.read_text()
    assert len(text.splitlines()) <= MAX_MODULE_LINES
    long = [
        f"{node.name} ({_code_lines(node)} lines)"
        for node in ast.walk(ast.parse(text))
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef)
        and _code_lines(node) > MAX_FUNCTION_LINES
    ]
    assert not long, f"functions over {MAX_FUNCTION_LINES} code lines: {long}"


def test_only_the_package_is_importable_from_the_top_level():
    """``eval`` is a folder of scripts, never a module that would shadow a well-known name
    in a user's environment; the bundled data is package data inside the package, not a
    top-level folder."""
    root = PACKAGE.parent
    assert not (root / "eval" / "__init__.py").exists()
    assert not (root / "datasets").exists()
    assert (PACKAGE / "datasets" / "objects").is_dir()
    assert not list((PACKAGE / "datasets").rglob("*.py"))


def test_dir_lists_every_lazily_loaded_name():
    """``dir()``, ``help()`` and tab completion see the names a package loads on first
    access: checked in a fresh interpreter, where none is loaded yet."""
    import subprocess
    import sys

    code = ("import importlib\n"
            "for name in ('o3d_spectral', 'o3d_spectral.harness', 'o3d_spectral.synthetic'):\n"
            "    package = importlib.import_module(name)\n"
            "    missing = set(package.__all__) - set(dir(package))\n"
            "    assert not missing, (name, sorted(missing))\n")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=PACKAGE.parent, timeout=120)
    assert run.returncode == 0, run.stderr[-2000:]
