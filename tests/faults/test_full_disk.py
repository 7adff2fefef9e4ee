"""A full disk while writing (simulated: ENOSPC from a write or ``fsync``).

The file being replaced is left as it was (never truncated), no temporary file is left behind,
a journal keeps its finished rows, and the command line reports it in one line with a non-zero
exit; once there is room again, the same command finishes the run.
"""

from __future__ import annotations

import errno
import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any, TextIO

import pytest
from fault_harness import LOCK_FILE, compare_trees, hidden_entries

import energy_margin.runs.journal as journal_module
from energy_margin.cli import main
from energy_margin.data.scores_file import CONFIG_FILE, JOURNAL_FILE, SCORES_FILE
from energy_margin.design.sweep_display import SweepDisplay
from energy_margin.runs.files import atomic_write_text, write_json
from energy_margin.runs.journal import Journal

ANALYZE = ["--expansions", "5", "--no-progress"]


def _full() -> OSError:
    return OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def _name(fd: int) -> str:
    try:
        return os.readlink(f"/proc/self/fd/{fd}")
    except OSError:
        return ""


def full_at_fsync(monkeypatch: pytest.MonkeyPatch, match: Callable[[str], bool]) -> list[str]:
    """``os.fsync`` of a file whose path ``match`` es fails with ENOSPC; the paths it failed on."""
    real = os.fsync
    failed: list[str] = []

    def fsync(fd: int) -> None:
        name = _name(fd)
        if match(name):
            failed.append(name)
            raise _full()
        real(fd)

    monkeypatch.setattr(os, "fsync", fsync)
    return failed


class _FillingStream:
    """A text stream whose ``write`` puts half the text on disk, then finds the disk full."""

    def __init__(self, stream: TextIO) -> None:
        self.stream = stream

    def write(self, text: str) -> int:
        self.stream.write(text[: len(text) // 2])
        self.stream.flush()
        raise _full()

    def __getattr__(self, name: str) -> Any:
        return getattr(self.stream, name)

    def __enter__(self) -> _FillingStream:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stream.close()


def full_at_write(monkeypatch: pytest.MonkeyPatch, match: Callable[[str], bool]) -> list[str]:
    """Writes to a file opened by ``os.fdopen`` (atomic writes) whose path ``match`` es fail half-way with ENOSPC."""
    real = os.fdopen
    failed: list[str] = []

    def fdopen(fd: int, *args: Any, **kwargs: Any) -> Any:
        name = _name(fd)
        stream = real(fd, *args, **kwargs)
        if match(name):
            failed.append(name)
            return _FillingStream(stream)
        return stream

    monkeypatch.setattr(os, "fdopen", fdopen)
    return failed


def full_at_append(monkeypatch: pytest.MonkeyPatch, after: int) -> list[str]:
    """Journal appends after the first ``after`` ones write half their line, then fail with ENOSPC."""
    real = journal_module.append_line
    calls: list[str] = []

    def append_line(stream: TextIO, line: str) -> None:
        calls.append(line)
        if len(calls) <= after:
            real(stream, line)
            return
        stream.write(line[: len(line) // 2])
        stream.flush()
        raise _full()

    monkeypatch.setattr(journal_module, "append_line", append_line)
    return calls


def temporary_of(name: str) -> Callable[[str], bool]:
    """Whether a path is an atomic write's temporary file for ``name``."""
    return lambda path: os.path.basename(path).startswith(f".{name}.")


FULL = {"fsync": full_at_fsync, "write": full_at_write}


# ---------------------------------------------------------------- the file helpers


@pytest.mark.parametrize("where", list(FULL))
def test_atomic_write_on_a_full_disk_keeps_the_old_file(
    where: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "table.csv"
    path.write_text("a,b\n1,2\n")
    failed = FULL[where](monkeypatch, temporary_of("table.csv"))
    with pytest.raises(OSError) as caught:
        atomic_write_text(path, "a,b\n" + "3,4\n" * 1000)
    assert caught.value.errno == errno.ENOSPC
    assert len(failed) == 1
    assert path.read_text() == "a,b\n1,2\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["table.csv"]


@pytest.mark.parametrize("where", list(FULL))
def test_atomic_write_on_a_full_disk_creates_nothing(
    where: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    FULL[where](monkeypatch, temporary_of("new.json"))
    with pytest.raises(OSError, match="No space left on device"):
        write_json(tmp_path / "new.json", {"rows": list(range(100))})
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("where", list(FULL))
def test_write_json_on_a_full_disk_keeps_the_old_document(
    where: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "settings.json"
    write_json(path, {"seed": 1})
    before = path.read_bytes()
    FULL[where](monkeypatch, temporary_of("settings.json"))
    with pytest.raises(OSError, match="No space left on device"):
        write_json(path, {"seed": 2, "more": "x" * 10_000})
    assert path.read_bytes() == before
    assert json.loads(before) == {"seed": 1}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["settings.json"]


def _journal(path: Path) -> Journal[int]:
    def parse(line: str) -> dict[str, Any] | None:
        cells = line.rstrip("\n").split(",")
        if not line.endswith("\n") or len(cells) != 2 or not all(c.isdigit() for c in cells):
            return None
        return {"key": int(cells[0]), "value": int(cells[1])}

    return Journal(
        path,
        header="key,value\n",
        format_row=lambda row: f"{row['key']},{row['value']}",
        parse_row=parse,
        key=lambda row: int(row["key"]),
    )


def test_a_journal_append_on_a_full_disk_keeps_the_finished_rows(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "run.journal.csv"
    journal = _journal(path)
    journal.rewrite({})
    full_at_append(monkeypatch, after=3)
    with journal, pytest.raises(OSError, match="No space left on device"):
        for key in range(10):
            journal.append({"key": key, "value": 1000 + key})
    # Three whole rows and the torn half of the fourth, which reading drops.
    assert path.read_text().count("\n") == 4
    assert _journal(path).read() == {k: {"key": k, "value": 1000 + k} for k in range(3)}
    monkeypatch.undo()
    # Room again: the journal is rewritten without the torn line and appended to.
    resumed = _journal(path)
    rows = resumed.read()
    resumed.rewrite(rows)
    with resumed:
        for key in range(3, 10):
            resumed.append({"key": key, "value": 1000 + key})
    assert path.read_text() == "key,value\n" + "".join(f"{k},{1000 + k}\n" for k in range(10))


def test_a_journal_rewrite_on_a_full_disk_keeps_the_old_journal(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "run.journal.csv"
    journal = _journal(path)
    journal.rewrite({k: {"key": k, "value": k} for k in range(5)})
    before = path.read_bytes()
    full_at_write(monkeypatch, temporary_of(path.name))
    with pytest.raises(OSError, match="No space left on device"):
        journal.rewrite({k: {"key": k, "value": k} for k in range(500)})
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]


# ---------------------------------------------------------------- through the command line


def _one_line_full_disk(code: int, err: str, *, log: bool = False) -> None:
    """What the user sees of a full disk: one line (after a command's log lines), exit status 2, no traceback."""
    assert code == 2
    assert "Traceback" not in err
    lines = err.splitlines()
    if not log:
        assert len(lines) == 1, err
    assert [line for line in lines if line.startswith("energy-margin")] == lines[-1:], err
    assert lines[-1].startswith("energy-margin: error: "), err
    assert "no space left on device" in lines[-1].lower(), err
    assert lines[-1].endswith("make room and run the same command again to resume"), err


def _analyzed(directory: Path, capsys: pytest.CaptureFixture[str]) -> Path:
    assert main(["analyze", str(directory), *ANALYZE]) == 0
    capsys.readouterr()
    return directory


def test_analyze_with_the_disk_full_mid_journal_resumes_once_there_is_room(
    copy_dataset: Callable[[str], Path], capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    reference = _analyzed(copy_dataset("reference"), capsys)
    directory = copy_dataset("run")
    full_at_append(monkeypatch, after=2)
    code = main(["analyze", str(directory), *ANALYZE])
    captured = capsys.readouterr()
    _one_line_full_disk(code, captured.err)
    assert captured.out == ""
    # The settings are whole, the two finished rows kept, no scores.csv, no lock, no temporary file.
    assert json.loads((directory / CONFIG_FILE).read_text()) == json.loads((reference / CONFIG_FILE).read_text())
    assert len((directory / JOURNAL_FILE).read_text().splitlines()) == 1 + 2 + 1  # header, 2 rows, a torn one
    assert not (directory / SCORES_FILE).exists()
    assert hidden_entries(directory) == []
    monkeypatch.undo()
    assert main(["analyze", str(directory), *ANALYZE]) == 0
    assert capsys.readouterr().out.splitlines() == [f"wrote {directory / SCORES_FILE}"]
    comparison = compare_trees(reference, directory)
    assert comparison.by_file == {SCORES_FILE: 6, JOURNAL_FILE: 6}


@pytest.mark.parametrize("where", list(FULL))
def test_analyze_with_the_disk_full_at_its_scores_leaves_no_torn_scores(
    where: str,
    copy_dataset: Callable[[str], Path],
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    reference = _analyzed(copy_dataset("reference"), capsys)
    directory = copy_dataset("run")
    failed = FULL[where](monkeypatch, temporary_of(SCORES_FILE))
    code = main(["analyze", str(directory), *ANALYZE])
    _one_line_full_disk(code, capsys.readouterr().err)
    assert len(failed) == 1
    assert not (directory / SCORES_FILE).exists()  # never a truncated one
    assert len((directory / JOURNAL_FILE).read_text().splitlines()) == 1 + 6  # every row is in the journal
    assert hidden_entries(directory) == []
    monkeypatch.undo()
    assert main(["analyze", str(directory), *ANALYZE]) == 0
    compare_trees(reference, directory)


@pytest.mark.parametrize("name", [CONFIG_FILE, JOURNAL_FILE])
def test_a_rerun_with_the_disk_full_leaves_the_run_as_it_was(
    name: str, tiny_dataset: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The settings rewritten on every rerun, the journal rewritten on resuming: both left whole."""
    _analyzed(tiny_dataset, capsys)
    if name == JOURNAL_FILE:
        (tiny_dataset / SCORES_FILE).unlink()  # as if killed before its scores: the rerun resumes the journal
    before = {p.name: p.read_bytes() for p in tiny_dataset.iterdir()}
    failed = full_at_fsync(monkeypatch, temporary_of(name))
    code = main(["analyze", str(tiny_dataset), *ANALYZE])
    _one_line_full_disk(code, capsys.readouterr().err)
    assert len(failed) == 1
    assert {p.name: p.read_bytes() for p in tiny_dataset.iterdir()} == before
    assert not (tiny_dataset / LOCK_FILE).exists()


def test_a_sweep_with_the_disk_full_at_its_results_keeps_the_previous_results(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(SweepDisplay, "save", lambda self, path, **options: None)  # the tables are the point
    out = tmp_path / "sweep"
    argv = ["sweep", "--task", "pushing", "--param", "pusher_width=0.6,0.8", "--trajectories", "2", "--frames", "2"]
    argv += ["--objects", "2", "--seed", "3", "--expansions", "8", "--bootstrap", "20", "--out", str(out)]
    assert main(argv) == 0
    capsys.readouterr()
    results = out / "results.json"
    before = results.read_bytes()
    failed = full_at_write(monkeypatch, temporary_of(results.name))
    code = main(argv)
    _one_line_full_disk(code, capsys.readouterr().err, log=True)  # after "sweep [1/2] ..." lines
    assert len(failed) == 1
    assert results.read_bytes() == before
    assert json.loads(before)["rows"]
    assert hidden_entries(out) == []
