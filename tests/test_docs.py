"""The documentation covers the public interface and stays findable.

Every public name (the ``__all__`` of the package and of its documented subpackages) has
a docstring and an entry in the API reference (``docs/reference/*.md``, rendered by
``mkdocs build --strict`` in ``.ci/run``); the README fits on about one screen and links
every page of ``docs/``.
"""

from __future__ import annotations

import importlib
import inspect
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
PACKAGES = ("o3d_spectral", "o3d_spectral.servo", "o3d_spectral.synthetic",
            "o3d_spectral.harness")


def reference_entries() -> set[str]:
    """The last part of every ``::: dotted.name`` in the API reference."""
    text = "\n".join(p.read_text() for p in (DOCS / "reference").glob("*.md"))
    return {m.rsplit(".", 1)[-1] for m in re.findall(r"^::: ([\w.]+)", text, re.MULTILINE)}


def public_names() -> list[tuple[str, str]]:
    return [(package, name) for package in PACKAGES
            for name in importlib.import_module(package).__all__]


@pytest.mark.parametrize(("package", "name"), public_names(),
                         ids=lambda value: value)
def test_every_public_name_has_a_docstring_and_a_reference_entry(package, name):
    obj = getattr(importlib.import_module(package), name)
    if inspect.isclass(obj) or inspect.isroutine(obj) or callable(obj):
        assert inspect.getdoc(obj), f"{package}.{name} has no docstring"
    if package == "o3d_spectral.harness" and name in ("Symmetry", "model_symmetry"):
        package = "o3d_spectral.synthetic"  # documented with the models
    assert name in reference_entries(), f"{package}.{name} is not in docs/reference/"


def test_the_readme_fits_on_a_screen_and_links_every_page():
    readme = (ROOT / "README.md").read_text()
    assert len(readme.splitlines()) < 120
    lines = readme.splitlines()
    assert lines[3:5] == [
        "./setup.sh && .venv/bin/o3d-spectral demo --out out/demo",
        "./setup.sh dev && .venv/bin/python -m pytest -q",
    ]
    pages = {p.name for p in DOCS.glob("*.md")} - {"index.md"}
    linked = set(re.findall(r"\]\(docs/([\w-]+\.md)\)", readme))
    assert pages <= linked, f"pages the README does not link: {sorted(pages - linked)}"
