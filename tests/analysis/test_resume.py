"""Interrupting a real ``energy-margin analyze`` process (SIGKILL, Ctrl-C) and resuming it."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.run import analyze
from energy_margin.cli import main
from energy_margin.data.generate import generate_dataset
from energy_margin.data.scores_file import COLUMNS, CONFIG_FILE, JOURNAL_FILE, SCORES_FILE, load_scores, read_journal

# 3 objects x 4 trajectories x 5 frames = 20 frames of about 70 ms each: a run lasts a second or two,
# long enough to be interrupted after its first rows.
EXPANSIONS = 200
SHAPE = {"n_objects": 3, "n_trajectories": 4, "n_frames": 5}
N_ROWS = 4 * 5
DETERMINISTIC = tuple(c for c in COLUMNS if c not in ("runtime_s", "physics_s"))
TIMEOUT = 120.0
INTERRUPTED = "energy-margin: interrupted; run the same command again to resume"


def _command(directory: Path, workers: int) -> list[str]:
    return [
        sys.executable,
        "-m",
        "energy_margin",
        "analyze",
        str(directory),
        "--expansions",
        str(EXPANSIONS),
        # The tree's own score by name: the trees alone, the quickest rows to reach the journal.
        "--continuation",
        "0",
        "--no-progress",
        "--workers",
        str(workers),
    ]


def _table(directory: Path) -> dict[tuple[int, int], tuple[Any, ...]]:
    """Deterministic columns of scores.csv by (trajectory, frame); fails on a duplicated row."""
    scores = load_scores(directory)
    table: dict[tuple[int, int], tuple[Any, ...]] = {}
    for i in range(len(scores["frame"])):
        key = (int(scores["trajectory"][i]), int(scores["frame"][i]))
        assert key not in table, f"duplicated row {key}"
        table[key] = tuple(scores[name][i].item() for name in DETERMINISTIC)
    return table


def _complete_rows(journal: Path) -> list[str]:
    """Lines of the journal that are whole rows (the header and a torn last line excluded)."""
    lines = journal.read_text().splitlines(keepends=True)
    return [line for line in lines[1:] if line.endswith("\n") and line.count(",") == len(COLUMNS) - 1]


def _child_pids(pid: int) -> list[int]:
    children = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            stat = Path(f"/proc/{entry}/stat").read_text()
        except OSError:
            continue
        if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
            children.append(int(entry))
    return children


def _alive(pid: int) -> bool:
    """Whether ``pid`` is a live (not zombie) energy-margin process."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        cmdline = Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return False
    return state != "Z" and b"energy_margin" in cmdline


@pytest.fixture(scope="module")
def source(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("resume") / "source"
    generate_dataset("pushing", out=out, seed=0, **SHAPE)
    return out


@pytest.fixture(scope="module")
def reference(source: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[tuple[int, int], tuple[Any, ...]]:
    """Scores of an uninterrupted run (in this process) of the same dataset."""
    target = tmp_path_factory.mktemp("resume-reference") / "data"
    shutil.copytree(source, target)
    analyze(target, AnalyzerConfig(expansions=EXPANSIONS, continuation=0), seed=0, workers=2, progress=False)
    table = _table(target)
    assert sorted(table) == [(t, k) for t in range(SHAPE["n_trajectories"]) for k in range(SHAPE["n_frames"])]
    return table


@pytest.fixture
def dataset(source: Path, tmp_path: Path) -> Path:
    target = tmp_path / "data"
    shutil.copytree(source, target)
    return target


@pytest.fixture
def processes() -> Iterator[Callable[..., subprocess.Popen[bytes]]]:
    """Start processes in their own session; whatever is left of them is killed afterwards."""
    started: list[tuple[subprocess.Popen[bytes], list[int]]] = []

    def start(command: list[str], out: Path) -> subprocess.Popen[bytes]:
        # Output goes to files, not pipes: orphaned workers could hold a pipe open forever.
        with (out.with_suffix(".out")).open("wb") as stdout, (out.with_suffix(".err")).open("wb") as stderr:
            proc = subprocess.Popen(command, stdout=stdout, stderr=stderr, start_new_session=True)
        started.append((proc, []))
        return proc

    start.started = started  # type: ignore[attr-defined]
    yield start
    for proc, children in started:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=TIMEOUT)
        for pid in children:
            if _alive(pid):
                os.kill(pid, signal.SIGKILL)


def _wait_for_rows(proc: subprocess.Popen[bytes], journal: Path, count: int) -> None:
    deadline = time.monotonic() + TIMEOUT
    while time.monotonic() < deadline:
        if journal.is_file() and len(_complete_rows(journal)) >= count:
            return
        assert proc.poll() is None, f"analyze exited early with {proc.returncode}"
        time.sleep(0.005)
    pytest.fail(f"no {count} journal rows after {TIMEOUT} s")


def _interrupt(
    start: Callable[..., subprocess.Popen[bytes]], directory: Path, workers: int, how: signal.Signals
) -> tuple[subprocess.Popen[bytes], list[str], list[int]]:
    """Start analyze, wait for two journal rows, send ``how``; return the process, rows and workers."""
    proc = start(_command(directory, workers), directory.parent / "run")
    journal = directory / JOURNAL_FILE
    _wait_for_rows(proc, journal, 2)
    children = _child_pids(proc.pid)
    start.started[-1][1].extend(children)  # type: ignore[attr-defined]
    if workers > 1:
        assert len(children) == workers
    if how == signal.SIGINT:
        os.killpg(proc.pid, signal.SIGINT)  # like Ctrl-C in a terminal: the whole process group
    else:
        proc.send_signal(how)
    proc.wait(timeout=TIMEOUT)
    # Rows written before the signal: complete lines, whatever arrived after the snapshot included.
    return proc, _complete_rows(journal), children


def _resume_and_check(
    directory: Path,
    workers: int,
    before: list[str],
    reference: dict[tuple[int, int], tuple[Any, ...]],
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert not (directory / SCORES_FILE).exists()
    assert 2 <= len(before) < N_ROWS, "the run was not interrupted mid-way"
    json.loads((directory / CONFIG_FILE).read_text())  # analysis.json is whole

    # The same command again, run in this process (what __main__ runs, without a new interpreter).
    capsys.readouterr()
    assert main(_command(directory, workers)[3:]) == 0
    captured = capsys.readouterr()
    assert captured.out.splitlines() == [f"wrote {directory / SCORES_FILE}"]
    assert captured.err == ""

    rows = (directory / SCORES_FILE).read_text().splitlines(keepends=True)
    assert rows[0] == ",".join(COLUMNS) + "\n"
    assert len(rows) == 1 + N_ROWS
    assert len(set(rows[1:])) == N_ROWS
    assert _table(directory) == reference  # every column but the timings
    # Rows finished before the interruption were kept, not recomputed: their timings are byte-identical.
    for line in before:
        assert line in rows, f"row recomputed: {line!r}"
    journal = read_journal(directory / JOURNAL_FILE)
    assert len(journal) == N_ROWS
    assert len((directory / JOURNAL_FILE).read_text().splitlines()) == 1 + N_ROWS
    # Atomic writes leave no temporary files behind.
    leftovers = sorted(p.name for p in directory.iterdir() if p.name.startswith("."))
    assert leftovers == []
    assert sorted(p.name for p in directory.iterdir()) == sorted(
        ["dataset.json", "frames.npz", CONFIG_FILE, JOURNAL_FILE, SCORES_FILE]
    )


@pytest.mark.slow
@pytest.mark.parametrize("workers", [1, 2])
def test_sigkill_then_resume(
    dataset: Path,
    processes: Callable[..., subprocess.Popen[bytes]],
    reference: dict[tuple[int, int], tuple[Any, ...]],
    workers: int,
    capsys: pytest.CaptureFixture[str],
) -> None:
    proc, before, children = _interrupt(processes, dataset, workers, signal.SIGKILL)
    assert proc.returncode == -signal.SIGKILL
    # A SIGKILLed parent cannot stop its workers (see test_workers_exit_when_the_parent_is_killed);
    # stop them here so they cannot interfere with the resumed run's timing.
    for pid in children:
        if _alive(pid):
            os.kill(pid, signal.SIGKILL)
    _resume_and_check(dataset, workers, before, reference, capsys)


@pytest.mark.slow
@pytest.mark.parametrize("workers", [1, 2])
def test_ctrl_c_exits_130_then_resume(
    dataset: Path,
    processes: Callable[..., subprocess.Popen[bytes]],
    reference: dict[tuple[int, int], tuple[Any, ...]],
    workers: int,
    capsys: pytest.CaptureFixture[str],
) -> None:
    proc, before, children = _interrupt(processes, dataset, workers, signal.SIGINT)
    assert proc.returncode == 130
    err = (dataset.parent / "run.err").read_text()
    assert err.splitlines() == [INTERRUPTED], err
    assert (dataset.parent / "run.out").read_text() == ""
    # The parent stopped its workers before exiting.
    deadline = time.monotonic() + 10
    while any(_alive(pid) for pid in children) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not any(_alive(pid) for pid in children)
    _resume_and_check(dataset, workers, before, reference, capsys)


@pytest.mark.slow
def test_workers_exit_when_the_parent_is_killed(
    dataset: Path, processes: Callable[..., subprocess.Popen[bytes]]
) -> None:
    proc, _, children = _interrupt(processes, dataset, 2, signal.SIGKILL)
    assert proc.returncode == -signal.SIGKILL
    assert len(children) == 2
    deadline = time.monotonic() + 3
    while any(_alive(pid) for pid in children) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(_alive(pid) for pid in children), "orphaned workers still running"


# ---------------------------------------------------------------- torn journals (in process)

SMALL = AnalyzerConfig(expansions=20, continuation=0)


@pytest.fixture(scope="module")
def tiny_reference(tiny_dataset_source: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    target = tmp_path_factory.mktemp("torn-reference") / "data"
    shutil.copytree(tiny_dataset_source, target)
    analyze(target, SMALL, seed=4, progress=False)
    return target


def test_resume_from_a_journal_cut_at_any_byte(tiny_reference: Path, tiny_dataset_source: Path, tmp_path: Path) -> None:
    """A crash can cut the journal anywhere in its last row: every cut resumes cleanly."""
    journal_bytes = (tiny_reference / JOURNAL_FILE).read_bytes()
    lines = journal_bytes.splitlines(keepends=True)
    header, rows = lines[0], lines[1:]
    reference = _table(tiny_reference)
    start = len(header) + len(rows[0]) + len(rows[1])  # two whole rows, then a cut inside the third
    third = rows[2]
    commas = [i for i, byte in enumerate(third) if byte == ord(",")]
    # Cuts before, on and after every separator, inside numbers, and around the final newline.
    offsets = sorted({0, 1, 2, *commas, *(c + 1 for c in commas), len(third) - 2, len(third) - 1, len(third)})
    for number, cut in enumerate(start + offset for offset in offsets):
        directory = tmp_path / f"cut{number}"
        shutil.copytree(tiny_dataset_source, directory)
        shutil.copy(tiny_reference / CONFIG_FILE, directory / CONFIG_FILE)
        (directory / JOURNAL_FILE).write_bytes(journal_bytes[:cut])
        analyze(directory, SMALL, seed=4, progress=False)
        assert _table(directory) == reference, cut
        final = (directory / SCORES_FILE).read_bytes().splitlines(keepends=True)
        assert len(final) == 1 + len(rows)
        kept = rows[:3] if cut == start + len(rows[2]) else rows[:2]
        assert all(row in final for row in kept), cut
        journal_lines = (directory / JOURNAL_FILE).read_bytes().splitlines(keepends=True)
        assert len(journal_lines) == 1 + len(rows)
        assert all(line.endswith(b"\n") for line in journal_lines)
        assert [p.name for p in directory.iterdir() if p.name.startswith(".")] == []
        shutil.rmtree(directory)


def test_resume_from_a_journal_with_garbage_bytes(
    tiny_reference: Path, tiny_dataset_source: Path, tmp_path: Path
) -> None:
    directory = tmp_path / "garbage"
    shutil.copytree(tiny_dataset_source, directory)
    shutil.copy(tiny_reference / CONFIG_FILE, directory / CONFIG_FILE)
    lines = (tiny_reference / JOURNAL_FILE).read_bytes().splitlines(keepends=True)
    # Invalid UTF-8, a NUL-filled block (as left by a crash on some file systems), a row cut short.
    junk = b"\xff\xfe\x00garbage\n" + b"\x00" * 64 + b"\n" + lines[3][:10]
    (directory / JOURNAL_FILE).write_bytes(lines[0] + lines[1] + junk)
    analyze(directory, SMALL, seed=4, progress=False)
    assert _table(directory) == _table(tiny_reference)
    assert lines[1] in (directory / SCORES_FILE).read_bytes().splitlines(keepends=True)
