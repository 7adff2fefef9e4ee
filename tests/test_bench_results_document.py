"""benchmarks/results_document.py: the arguments, the head and the writing the results benchmarks share."""

from __future__ import annotations

import datetime
import json
from pathlib import Path

import pytest

from bench_modules import load_benchmark


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("results_document")


def test_work_and_out_are_required_and_workers_default_to_two(bench, tmp_path: Path) -> None:
    parser = bench.work_arguments("First line.\n\nMore.")
    assert parser.description == "First line."
    args = parser.parse_args(["--work", str(tmp_path), "--out", str(tmp_path / "f.json")])
    assert (args.work, args.out, args.workers) == (tmp_path, tmp_path / "f.json", 2)
    with pytest.raises(SystemExit):
        parser.parse_args(["--work", str(tmp_path)])


def test_without_workers_there_is_no_workers_option(bench) -> None:
    parser = bench.work_arguments(None, workers=False, work_help="where the generated sets go")
    args = parser.parse_args(["--work", "w", "--out", "o"])
    assert not hasattr(args, "workers")
    assert "where the generated sets go" in parser.format_help()


def test_the_head_names_the_command_the_date_and_the_machine(bench) -> None:
    head = bench.document_head("unseen_sets.py")
    assert list(head) == ["command", "date", "machine"]
    assert head["command"] == "python benchmarks/unseen_sets.py --work WORK --out FILE"
    assert head["date"] == datetime.date.today().isoformat()
    assert "logical CPUs" in head["machine"]


def test_a_document_is_written_in_a_new_folder_as_indented_json(bench, tmp_path: Path) -> None:
    path = tmp_path / "new" / "found.json"
    bench.write_document(path, {"b": 1, "a": [0.5]})
    text = path.read_text(encoding="utf-8")
    assert json.loads(text) == {"b": 1, "a": [0.5]}
    assert text == json.dumps({"b": 1, "a": [0.5]}, indent=2) + "\n"
