"""The journal, the result tables and the display base of the run layer."""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

import pytest

from energy_margin.runs import Journal
from energy_margin.runs.display import Display
from energy_margin.runs.tables import Column, field, format_table, write_csv, write_json


def _journal(path: Path) -> Journal[int]:
    def parse(line: str) -> dict[str, Any] | None:
        parts = line.rstrip("\n").split(",")
        if not line.endswith("\n") or len(parts) != 2 or not parts[0].isdigit():
            return None
        return {"i": int(parts[0]), "v": parts[1]}

    return Journal(
        path, header="i,v\n", format_row=lambda r: f"{r['i']},{r['v']}", parse_row=parse, key=lambda r: r["i"]
    )


def test_journal_appends_durably_and_drops_torn_foreign_and_duplicate_lines(tmp_path: Path) -> None:
    journal = _journal(tmp_path / "j.csv")
    with journal:
        journal.append({"i": 1, "v": "a"})
        journal.append({"i": 0, "v": "b"})
    with (tmp_path / "j.csv").open("a") as stream:
        stream.write("1,again\nnot a row\n2,tor")
    rows = journal.read()
    assert rows == {1: {"i": 1, "v": "a"}, 0: {"i": 0, "v": "b"}}
    journal.rewrite(rows)
    assert (tmp_path / "j.csv").read_text() == "i,v\n0,b\n1,a\n"
    assert _journal(tmp_path / "absent.csv").read() == {}


def test_one_csv_writer_for_every_table(tmp_path: Path) -> None:
    rows = [{"name": "a", "value": 0.1 + 0.2, "list": [1, 2], "missing": None, "extra": 1}, {"name": "b"}]
    path = write_csv(tmp_path / "t.csv", rows, ["name", "value", "list", "missing"])
    read = list(csv.DictReader(path.open()))
    assert read[0] == {"name": "a", "value": repr(0.1 + 0.2), "list": "[1, 2]", "missing": ""}
    assert float(read[0]["value"]) == 0.1 + 0.2  # exact round trip
    assert read[1] == {"name": "b", "value": "", "list": "", "missing": ""}
    assert json.loads(write_json(tmp_path / "t.json", {"b": 1, "a": [1]}).read_text()) == {"a": [1], "b": 1}


def test_text_tables_widen_to_their_cells() -> None:
    rows = [{"method": "est", "ap": 0.91234}, {"method": "monte-carlo", "ap": None}]
    text = format_table(rows, [field("method", width=6), field("ap", "capture AP", digits=3)])
    lines = text.splitlines()
    assert lines[0] == "     method capture AP" and set(lines[1]) == {"-"}
    assert lines[2] == "        est      0.912" and lines[3] == "monte-carlo        n/a"
    left = format_table(rows, [Column("m", lambda r: r["method"], align="<")])
    assert left.splitlines()[2] == "est"


class _Line(Display):
    def __init__(self, values: list[float]) -> None:
        self.values = values

    def draw(self, plt: Any) -> Any:
        figure, axes = plt.subplots()
        axes.plot(self.values)
        return figure


def test_a_display_draws_only_when_asked_and_saves_atomically(tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    display = _Line([0.0, 1.0])
    assert display.figure_ is None
    assert display.plot().figure_ is not None
    path = display.save(tmp_path / "line.png")
    assert path is not None and path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert [p.name for p in tmp_path.iterdir()] == ["line.png"]


def test_close_all_ends_the_line_of_a_bar_left_open(capsys: pytest.CaptureFixture[str]) -> None:
    from energy_margin.runs.progress import close_all, progress_bar

    bar = progress_bar(4, desc="analyze", enabled=True)
    bar.update(1)
    close_all()  # as the command line does before its last line, whatever was interrupted
    assert bar.disable
    assert capsys.readouterr().err.endswith("\n")
    close_all()  # nothing open: nothing happens


def test_close_all_skips_a_bar_interrupted_while_it_was_built() -> None:
    # An interrupt inside tqdm's constructor (starting its monitor thread) leaves a registered,
    # half-built bar whose close() raises AttributeError; the command's last line must still come.
    from tqdm import tqdm

    from energy_margin.runs.progress import close_all

    half_built = tqdm.__new__(tqdm)
    assert half_built in tqdm._instances and not hasattr(half_built, "disable")
    close_all()
    assert half_built not in tqdm._instances
    half_built.close()  # as when it is collected: nothing to raise
