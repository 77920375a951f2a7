"""Compile LaTeX tables with a real pdflatex and read back the PDF's text (pdftotext).

Both come with TeX Live and poppler (Debian: ``texlive-latex-base``,
``texlive-latex-recommended``, ``lmodern``, ``poppler-utils``; ``.ci/run`` installs
them). Where either is missing the tests that need them are skipped with that reason.
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

#: A paper's preamble: T1 fonts (Latin Modern), booktabs for the rules.
PAPER = r"\usepackage[T1]{fontenc}" "\n" r"\usepackage{lmodern}" "\n"

needs_latex = pytest.mark.skipif(
    shutil.which("pdflatex") is None or shutil.which("pdftotext") is None,
    reason="pdflatex or pdftotext is not installed (Debian: texlive-latex-base, "
           "texlive-latex-recommended, lmodern, poppler-utils)",
)


def compile_tables(tables: list[str], folder: Path, *, preamble: str = PAPER) -> str:
    """Typeset the LaTeX ``tables`` in one article (``preamble`` + booktabs) with pdflatex
    in ``folder`` and return the PDF's text; the LaTeX error in the assertion message
    when it does not compile."""
    folder.mkdir(parents=True, exist_ok=True)
    body = "\n\\clearpage\n".join(tables)
    (folder / "doc.tex").write_text(
        "\\documentclass{article}\n" + preamble + "\\usepackage{booktabs}\n"
        "\\begin{document}\n" + body + "\n\\end{document}\n", encoding="utf-8")
    run = subprocess.run(["pdflatex", "-interaction=nonstopmode", "-halt-on-error", "doc.tex"],
                         cwd=folder, capture_output=True, text=True, timeout=120)
    errors = [line for line in run.stdout.splitlines() if line.startswith("!")]
    assert run.returncode == 0, f"pdflatex failed: {errors or run.stdout[-2000:]}"
    log = (folder / "doc.log").read_text(encoding="utf-8", errors="replace")
    warnings = [line for line in log.splitlines() if "Missing character" in line]
    assert not warnings, warnings
    text = subprocess.run(["pdftotext", "-layout", "doc.pdf", "-"], cwd=folder,
                          capture_output=True, text=True, check=True, timeout=60)
    return text.stdout
