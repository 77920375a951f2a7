"""Result tables (:class:`~o3d_spectral.harness.tables.Table`) as GitHub Markdown,
LaTeX booktabs and CSV files; rows of dicts as a CSV file (the benchmarks' raw rows); a
benchmark's figure as a PNG file."""

from __future__ import annotations

import csv
import math
import re
from pathlib import Path

from o3d_spectral.harness.tables import Table

__all__ = ["markdown_text", "tex_prose", "tex_text", "to_latex", "to_markdown", "write_bench",
           "write_figure", "write_rows", "write_table"]


def _cell(value, kind: str, *, latex: bool) -> str:
    if kind == "text":
        return tex_text(str(value)) if latex else markdown_text(str(value))
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


#: LaTeX for each character that LaTeX reads as a command (``\ & % $ # _ { } ~ ^``),
#: sets as another glyph in its default OT1 encoding (``< > |``), or joins into a
#: ligature (`` ` ' ``, and ``--`` / ``,,`` by the rule in :data:`_TEX_CHARACTER`), and
#: for the few Unicode signs the harness's own headers use: each renders as itself
#: with and without ``\usepackage[T1]{fontenc}``.
_TEX = {
    "\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#", "_": r"\_",
    "{": r"\{", "}": r"\}", "~": r"\textasciitilde{}", "^": r"\textasciicircum{}",
    "<": r"\textless{}", ">": r"\textgreater{}", "|": r"\textbar{}",
    "`": r"\textasciigrave{}", "'": r"\textquotesingle{}", "-": "-{}", ",": ",{}",
    "²": "$^2$", "≤": r"$\le$", "≥": r"$\ge$", "±": r"$\pm$", "×": r"$\times$",
    "°": r"\textdegree{}",
}
#: The characters :data:`_TEX` replaces; a hyphen or comma only before another one.
_TEX_CHARACTER = re.compile(r"[\\&%$#_{}~^<>|`'²≤≥±×°]|-(?=-)|,(?=,)")
_CODE_SPAN = re.compile(r"`([^`]+)`")


def tex_text(text: str) -> str:
    """``text`` as LaTeX that typesets exactly ``text`` (line breaks become spaces).

    Examples
    --------
    >>> print(tex_text("fpfh&icp R^2 {x} my_method~v2"))
    fpfh\\&icp R\\textasciicircum{}2 \\{x\\} my\\_method\\textasciitilde{}v2
    """
    text = text.replace("\r", " ").replace("\n", " ")
    return _TEX_CHARACTER.sub(lambda match: _TEX[match.group()[0]], text)


def tex_prose(text: str) -> str:
    """A caption's Markdown (plain text with `` `code` `` spans) as LaTeX: the spans in
    ``\\texttt``, the rest typeset as written, its apostrophes as typographic ones."""
    parts = _CODE_SPAN.split(text)
    return "".join(
        tex_text(part).replace(_TEX["'"], "'") if k % 2 == 0
        else rf"\texttt{{{tex_text(part)}}}"
        for k, part in enumerate(parts)
    )


def markdown_text(text: str) -> str:
    """``text`` as one GitHub Markdown table cell: ``|`` escaped, line breaks as spaces."""
    return text.replace("\r", " ").replace("\n", " ").replace("|", r"\|")


def to_markdown(table: Table) -> str:
    """The table as a GitHub Markdown table (numbers right-aligned)."""
    columns = list(table.frame.columns)
    align = ["---" if table.formats[c] == "text" else "---:" for c in columns]
    header = " | ".join(markdown_text(str(c)) for c in columns)
    lines = [f"| {header} |", "| " + " | ".join(align) + " |"]
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
            rf"\caption{{{tex_prose(table.caption)}}}",
            rf"\label{{tab:{table.name}}}",
            rf"\begin{{tabular}}{{{spec}}}",
            r"\toprule",
            " & ".join(tex_text(str(c)) for c in columns) + r" \\",
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


def write_bench(out: Path, rows: list[dict], summary: list[dict], table: str,
                table_name: str = "summary.md") -> None:
    """A bench's outputs in the folder ``out`` (made): its ``rows`` as ``rows.csv``, its
    ``summary`` as ``summary.csv`` (:func:`write_rows`) and its Markdown ``table`` as
    ``table_name``."""
    out.mkdir(parents=True, exist_ok=True)
    write_rows(out / "rows.csv", rows)
    write_rows(out / "summary.csv", summary)
    (out / table_name).write_text(table)


def write_figure(fig, path: Path) -> Path:
    """A matplotlib figure laid out tightly and written to ``path`` (its folder made) at
    120 dpi, the benchmarks' figures' resolution."""
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    return path
