"""The documentation covers the public interface and stays findable.

Every public name (the ``__all__`` of the package and of its documented subpackages) has
a docstring and an entry in the API reference (``docs/reference/*.md``, rendered by
``mkdocs build --strict`` in ``.ci/run``); the README fits on about one screen and links
every page of ``docs/``; the generated figures of the README and the docs read as
``tools/docs_figures.py`` renders them from the stored bench outputs in ``docs/data/``,
each of which names its commit.
"""

from __future__ import annotations

import difflib
import importlib
import importlib.util
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


def docs_figures():
    """``tools/docs_figures.py`` as a module (``tools/`` is not a package)."""
    path = ROOT / "tools" / "docs_figures.py"
    spec = importlib.util.spec_from_file_location("docs_figures", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_figure_in_the_docs_is_rendered_from_a_stored_output():
    figures = docs_figures()
    docs = figures.rendered()
    assert ROOT / "README.md" in docs and DOCS / "results.md" in docs
    for path, (text, new) in docs.items():
        diff = "".join(difflib.unified_diff(
            text.splitlines(keepends=True), new.splitlines(keepends=True),
            str(path.relative_to(ROOT)), "rendered from docs/data"))
        assert text == new, (
            f"{path.relative_to(ROOT)} differs from its stored outputs: edit docs/data/ and run "
            f"python tools/docs_figures.py, not the figures\n{diff}")


def test_every_block_is_in_a_doc():
    figures = docs_figures()
    used = {m.group(2) for text, _ in figures.rendered().values()
            for m in figures.BLOCK.finditer(text)}
    assert used == set(figures.BLOCKS), f"blocks in no doc: {sorted(set(figures.BLOCKS) - used)}"


def test_an_edited_figure_fails_the_check(tmp_path, capsys):
    figures = docs_figures()
    doc = tmp_path / "results.md"
    text = (DOCS / "results.md").read_text()
    doc.write_text(text)
    figures.DOCS, figures.ROOT = (doc,), tmp_path  # the stored outputs stay docs/data's
    assert figures.main(["--check"]) == 0
    edited = text.replace("| full | 240 | 99.6% |", "| full | 240 | 99.7% |", 1)
    assert edited != text
    doc.write_text(edited)
    assert figures.main(["--check"]) == 1
    assert "-| full | 240 | 99.7% |" in capsys.readouterr().out
    assert doc.read_text() == edited  # --check changes nothing
    assert figures.main([]) == 0 and doc.read_text() == text


def test_every_stored_output_names_its_file_command_and_commit():
    for name, source in docs_figures().sources().items():
        assert (DOCS / "data" / source["file"]).is_file(), name
        assert source["command"].strip(), name
        assert re.fullmatch(r"[0-9a-f]{7,40}", source["commit"]), name


def test_the_results_page_stays_a_reference():
    assert len((DOCS / "results.md").read_text().splitlines()) <= 300


def test_every_constant_is_in_its_layers_catalogue_with_a_reason_and_the_page_is_current():
    """Every module-level numeric constant of the package lives in its layer's
    ``constants.py`` with its reason (``--check`` names any other), and
    ``docs/constants.md`` is what ``tools/constants.py`` writes from them now."""
    import subprocess
    import sys

    done = subprocess.run([sys.executable, str(ROOT / "tools" / "constants.py"), "--check"],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout
