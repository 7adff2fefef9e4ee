"""Quoted figures agree with the results files they name (tools/figures.py)."""

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))
import figures  # noqa: E402

sys.path.remove(str(ROOT / "tools"))


def test_every_quoted_figure_agrees_with_its_file() -> None:
    problems = figures.problems()
    assert not problems, "quoted figures that disagree with their files:\n" + "\n".join(map(str, problems))


def test_the_readme_quotes_its_figures_from_files() -> None:
    quoted = list(figures.quotes(ROOT / "README.md"))
    assert len(quoted) >= 16


def _page(tmp_path: Path, body: str) -> Path:
    (tmp_path / "results.json").write_text('{"a": {"b": 0.89523, "c/d": [1, 2]}, "t": "1 min 02 s"}', encoding="utf-8")
    (tmp_path / "table.csv").write_text("method,budget,ap\nest,300,0.8952\nest,1000,0.8946\n", encoding="utf-8")
    (tmp_path / "log.txt").write_text("first\n  second line  \n", encoding="utf-8")
    page = tmp_path / "page.md"
    page.write_text(body, encoding="utf-8")
    return page


@pytest.mark.parametrize(
    ("marker", "expected"),
    [
        ("results.json#/a/b :.3f", "0.895"),
        ("results.json#/a/c~1d/1", "2"),
        ("results.json#/t", "1 min 02 s"),
        ("table.csv#method=est,budget=1000/ap :.2f", "0.89"),
        ("log.txt#L2", "second line"),
        ("results.json#/a/b :neg.2f", "-0.90"),
        ("table.csv#method=est,budget=300/ap :neg", "-0.8952"),
        ("results.json#/a/b :ms.0f", "895"),
        ("results.json#/a/b :us,.0f", "895,230"),
    ],
)
def test_a_marker_reads_json_csv_and_text(tmp_path: Path, marker: str, expected: str) -> None:
    page = _page(tmp_path, f"x <!-- fig {marker} -->{expected}<!-- /fig --> y\n")
    (quote,) = figures.quotes(page, tmp_path)
    assert quote.error is None and quote.expected == expected == quote.quoted


@pytest.mark.parametrize(
    ("marker", "error"),
    [
        ("missing.json#/a", "no such file"),
        ("results.json#/a/x", "no key 'x'"),
        ("table.csv#method=est/ap", "2 rows match"),
        ("log.txt#L9", "no line"),
        ("results.json#/t :neg.1f", "not a number"),
    ],
)
def test_a_marker_to_a_missing_file_or_key_fails(tmp_path: Path, marker: str, error: str) -> None:
    page = _page(tmp_path, f"<!-- fig {marker} -->1<!-- /fig -->\n")
    (quote,) = figures.quotes(page, tmp_path)
    assert quote.error is not None and error in quote.error


def test_a_disagreeing_figure_fails_and_write_fixes_it(tmp_path: Path) -> None:
    page = _page(tmp_path, "AP <!-- fig results.json#/a/b :.3f -->0.900<!-- /fig -->.\n")
    (quote,) = figures.quotes(page, tmp_path)
    assert quote.quoted == "0.900" and quote.expected == "0.895"
    assert figures.write(page, tmp_path) == 1
    assert page.read_text(encoding="utf-8") == "AP <!-- fig results.json#/a/b :.3f -->0.895<!-- /fig -->.\n"
    assert figures.write(page, tmp_path) == 0


TABLE = """<!-- table table.csv where method=est
| budget | AP |
|---:|---:|
| {budget:.0f|–} | {ap:.3f} |
-->
ROWS<!-- /table -->
"""


def test_a_table_block_lists_every_matching_record_and_write_fills_it(tmp_path: Path) -> None:
    page = _page(tmp_path, TABLE.replace("ROWS", ""))
    (stale,) = figures.quotes(page, tmp_path)
    assert stale.quoted != stale.expected
    assert "lines, the file gives 6" in str(stale)
    assert figures.write(page, tmp_path) == 1
    (fresh,) = figures.quotes(page, tmp_path)
    assert fresh.quoted == fresh.expected == "\n| budget | AP |\n|---:|---:|\n| 300 | 0.895 |\n| 1000 | 0.895 |\n\n"
    page.write_text(page.read_text(encoding="utf-8").replace("| 1000 | 0.895 |", "| 1000 | 0.900 |"))
    (edited,) = figures.quotes(page, tmp_path)
    assert "'| 1000 | 0.900 |'" in str(edited)


def test_a_table_keeps_the_records_a_where_pattern_matches(tmp_path: Path) -> None:
    rows = "comparison,d\nest - rrt,0.1\nest lambda 5 - lambda 50,0.2\nest - distance,0.3\n"
    (tmp_path / "d.csv").write_text(rows, encoding="utf-8")
    kept = figures.records("d.csv", None, "comparison=est?-?*", tmp_path)
    assert [row["d"] for row in kept] == ["0.1", "0.3"]
    assert [row["d"] for row in figures.records("d.csv", None, "comparison=*lambda*", tmp_path)] == ["0.2"]
    assert figures.records("d.csv", None, "comparison=est", tmp_path) == []


def test_a_table_cell_may_stand_for_an_empty_or_zero_value() -> None:
    rows = [{"budget": "0", "s": ""}, {"budget": "10", "s": "0.5"}]
    assert figures.table_rows("| {budget:.0f|–} | {s:.1f|} |", rows) == "\n| – |  |\n| 10 | 0.5 |\n\n"
    with pytest.raises(figures.FigureError, match="no column 'x'"):
        figures.table_rows("| {x} |", rows)
