"""Result tables (:class:`~o3d_spectral.harness.tables.Table`) as GitHub Markdown,
LaTeX booktabs and CSV files; rows of dicts as a CSV file (the benchmarks' raw rows); a
benchmark's figure as a PNG file."""

from __future__ import annotations

import csv
import math
from pathlib import Path

from o3d_spectral.harness.tables import Table

__all__ = ["to_latex", "to_markdown", "write_table", "write_rows", "write_figure"]


def _cell(value, kind: str, *, latex: bool) -> str:
    if kind == "text":
        return _tex_text(str(value)) if latex else str(value)
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "--" if latex else "–"
    if kind == "int":
        return f"{int(value)}"
    if kind == "pct":
        return f"{100 * value:.1f}"
    if kind == "sci":
        mantissa, exponent = f"{value:.2e}".split("e")
        return rf"${mantissa}\times10^{{{int(exponent)}}}$" if latex else f"{value:.2e}"
    return f"{value:.{int(kind[1])}f}"


def _tex_text(text: str) -> str:
    """Plain text (Markdown code quotes dropped) made safe for LaTeX."""
    for plain, tex in (("`", ""), ("_", r"\_"), ("%", r"\%"), ("²", "$^2$"), ("≤", "$\\le$")):
        text = text.replace(plain, tex)
    return text


def to_markdown(table: Table) -> str:
    """The table as a GitHub Markdown table (numbers right-aligned)."""
    columns = list(table.frame.columns)
    align = ["---" if table.formats[c] == "text" else "---:" for c in columns]
    lines = ["| " + " | ".join(columns) + " |", "| " + " | ".join(align) + " |"]
    for row in table.frame.itertuples(index=False):
        cells = [_cell(v, table.formats[c], latex=False) for c, v in zip(columns, row, strict=True)]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def to_latex(table: Table) -> str:
    """The table as a LaTeX ``table`` with a booktabs ``tabular`` (``\\usepackage{booktabs}``)."""
    columns = list(table.frame.columns)
    spec = "".join("l" if table.formats[c] == "text" else "r" for c in columns)
    body = [
        " & ".join(
            _cell(v, table.formats[c], latex=True) for c, v in zip(columns, row, strict=True)
        )
        + r" \\"
        for row in table.frame.itertuples(index=False)
    ]
    return "\n".join(
        [
            r"\begin{table}[t]",
            r"\centering",
            rf"\caption{{{_tex_text(table.caption)}}}",
            rf"\label{{tab:{table.name}}}",
            rf"\begin{{tabular}}{{{spec}}}",
            r"\toprule",
            " & ".join(_tex_text(c) for c in columns) + r" \\",
            r"\midrule",
            *body,
            r"\bottomrule",
            r"\end{tabular}",
            r"\end{table}",
            "",
        ]
    )


def write_table(table: Table, out_dir: Path) -> list[Path]:
    """Write ``<name>.md``, ``<name>.tex`` and ``<name>.csv`` into ``out_dir``."""
    paths = [out_dir / f"{table.name}.{ext}" for ext in ("md", "tex", "csv")]
    paths[0].write_text(to_markdown(table))
    paths[1].write_text(to_latex(table))
    table.frame.to_csv(paths[2], index=False)
    return paths


def write_rows(path: Path, rows: list[dict]) -> None:
    """``rows`` as a CSV file at ``path`` (its folder made): one column per key, in the
    order the rows first hold them; nothing written when there are no rows."""
    if not rows:
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    fields = list(dict.fromkeys(key for row in rows for key in row))
    with open(path, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=fields)
        writer.writeheader()
        writer.writerows(rows)


def write_figure(fig, path: Path) -> Path:
    """A matplotlib figure laid out tightly and written to ``path`` (its folder made) at
    120 dpi, the benchmarks' figures' resolution."""
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    return path
