"""Tables as LaTeX and Markdown whatever the names in them: every special character
typeset as itself (compiled with pdflatex, read back with pdftotext), Markdown cells
that keep their columns."""

import re

import pytest

pandas = pytest.importorskip("pandas", reason="the harness extra is not installed")

from o3d_spectral.harness.tables import Table  # noqa: E402
from o3d_spectral.harness.writers import tex_prose, tex_text, to_latex, to_markdown  # noqa: E402
from tests.latex import compile_tables, needs_latex  # noqa: E402

HOSTILE = ["fpfh&icp", "gicp#2", "my_method~v2", "R^2 {x}", r"a\b $5 50%", "x<y>z|w",
           "don't --fast ,,no", "`tick`", "C:\\temp\\new"]
CAPTION = "fpfh&icp beats gicp#2 on 50% of R^2 {x}: `my_method~v2` and $5 # notes"


def hostile_table() -> Table:
    frame = pandas.DataFrame({"method": HOSTILE, "success (%)": [0.5] * len(HOSTILE),
                              "rotation error (deg) ≤ 5": [1.25] * len(HOSTILE)})
    return Table("hostile", CAPTION, frame,
                 {"method": "text", "success (%)": "pct", "rotation error (deg) ≤ 5": "f2"})


def test_every_special_character_is_escaped_once():
    assert tex_text("&%$#_{}") == r"\&\%\$\#\_\{\}"
    assert tex_text("a\\b~c^d") == r"a\textbackslash{}b\textasciitilde{}c\textasciicircum{}d"
    assert tex_text("<>|") == r"\textless{}\textgreater{}\textbar{}"
    # Ligatures broken: "--" would be an en dash, ",," a low quote, `` ' `` curly quotes.
    assert tex_text("a--b,,c") == "a-{}-b,{},c"
    assert tex_text("a-b, c") == "a-b, c"
    assert tex_text("line\nbreak") == "line break"
    assert tex_prose("the `x_1` model's") == r"the \texttt{x\_1} model's"


def test_markdown_cells_keep_their_columns():
    lines = to_markdown(hostile_table()).splitlines()
    unescaped = re.compile(r"(?<!\\)\|")
    assert {len(unescaped.findall(line)) for line in lines} == {4}
    assert any(r"| x<y>z\|w |" in line for line in lines)


@needs_latex
def test_hostile_names_compile_and_read_back_as_given(tmp_path):
    table = to_latex(hostile_table())
    text = compile_tables([table], tmp_path / "t1")
    flat = " ".join(text.split())
    for name in HOSTILE:
        assert name in flat, name
    assert "my_method~v2 and $5 # notes" in flat and "50% of R^2 {x}" in flat
    # And in a document with LaTeX's default (OT1) fonts.
    compile_tables([table], tmp_path / "ot1", preamble="")


@needs_latex
@pytest.mark.slow
def test_report_tables_of_a_hostile_suite_name_compile(tmp_path):
    from o3d_spectral.cli import main
    from o3d_spectral.synthetic.suite import make_suite

    name = r"we&you #2 ~50% {x}^ a\b"
    make_suite("full", 1, 0, tmp_path / name, progress=False)
    assert main(["eval", "--suite", str(tmp_path / name), "--out", str(tmp_path / "run"),
                 "--methods", "icp_point_to_point", "--workers", "1", "--quiet"]) == 0
    assert main(["report", str(tmp_path / "run"), "--out", str(tmp_path / "report")]) == 0
    tables = sorted((tmp_path / "report").glob("*.tex"))
    assert len(tables) >= 3
    text = compile_tables([path.read_text() for path in tables], tmp_path / "tex")
    assert f"C-1 ({name})" in " ".join(text.split())
