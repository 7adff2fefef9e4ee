"""Run a real ``energy-margin`` command, SIGKILL it at seeded random moments, resume it, compare.

A :class:`Command` is a command line run in a work directory of its own (its inputs copied
there, every path in the command line relative to it, so the paths a run records are the same
in every work directory). :func:`run_uninterrupted` runs it once and measures how long it takes;
:func:`kill_and_resume` starts it again and again in another work directory, SIGKILLs its
process group (the command and its worker processes) at moments drawn from a seeded
:class:`numpy.random.Generator` over that duration, until enough kills landed on a live
process, then lets one last rerun finish; :func:`compare_trees` checks that what it wrote is
what the uninterrupted run wrote.

The command runs in its own session (``start_new_session=True``), so ``os.killpg`` reaches its
workers too; its output goes to files, not pipes, which a stray worker could hold open.
"""

from __future__ import annotations

import csv
import io
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Iterable
from contextlib import suppress
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

import energy_margin

#: Columns and keys that are measured times: they differ between runs and are never compared.
TIMING = frozenset(
    {
        "runtime_s",
        "physics_s",
        "runtime_per_frame_s",
        "seconds",
        "seconds_per_decision",
        "decision_seconds",
        "seconds_per_frame",
        "s_per_frame",
        "elapsed_s",
        "started",
        "finished",
    }
)
TIMEOUT = 180.0
LOCK_FILE = ".energy-margin.lock"
SRC = Path(energy_margin.__file__).resolve().parents[1]


@dataclass(frozen=True)
class Command:
    """A command line and what it needs.

    Attributes:
        name: a short label (directories and messages).
        argv: the arguments after ``energy-margin``; paths in them are relative to the work directory.
        out: the directory the command writes (relative to the work directory), compared afterwards.
        inputs: what to copy into a fresh work directory first, by relative name.
        hide_matplotlib: run without matplotlib (no figures: the tables are what is compared, and
            drawing them is most of a tiny run's time).

    """

    name: str
    argv: tuple[str, ...]
    out: str
    inputs: dict[str, Path] = field(default_factory=dict)
    hide_matplotlib: bool = True

    def command_line(self) -> list[str]:
        return [sys.executable, "-m", "energy_margin", *self.argv]


@dataclass
class Run:
    """An uninterrupted run: where it wrote and how long it took."""

    workdir: Path
    seconds: float
    stdout: str
    stderr: str

    def out(self, command: Command) -> Path:
        return self.workdir / command.out


@dataclass
class KillReport:
    """What :func:`kill_and_resume` did."""

    attempts: int = 0
    kills: int = 0  # SIGKILLs that landed on a live process
    completed_before_kill: int = 0  # attempts that finished (exit 0) before their kill time
    kill_times: list[float] = field(default_factory=list)
    final_seconds: float = 0.0
    stderr: list[str] = field(default_factory=list)


def environment(hidden: Path | None) -> dict[str, str]:
    """This process's environment with the package (and a matplotlib-hiding folder) on the path."""
    env = dict(os.environ)
    parts = [str(hidden)] if hidden is not None else []
    parts.append(str(SRC))
    if env.get("PYTHONPATH"):
        parts.append(env["PYTHONPATH"])
    env["PYTHONPATH"] = os.pathsep.join(parts)
    env.pop("ENERGY_MARGIN_PROGRESS", None)
    env.pop("ENERGY_MARGIN_DEBUG", None)
    return env


def hidden_matplotlib(root: Path) -> Path:
    """A folder whose ``matplotlib`` package fails to import, as on an installation without it."""
    package = root / "matplotlib"
    package.mkdir(parents=True, exist_ok=True)
    (package / "__init__.py").write_text('raise ImportError("matplotlib is hidden in this test")\n')
    return root


def prepare(command: Command, workdir: Path) -> Path:
    """A fresh work directory holding the command's inputs."""
    workdir.mkdir(parents=True)
    for name, source in command.inputs.items():
        if source.is_dir():
            shutil.copytree(source, workdir / name)
        else:
            shutil.copy2(source, workdir / name)
    return workdir


class Processes:
    """Starts the command in its own session; whatever is left of its process groups is killed at the end."""

    def __init__(self, logs: Path, hidden: Path | None) -> None:
        self.logs = logs
        self.logs.mkdir(parents=True, exist_ok=True)
        self.hidden = hidden
        self.started: list[subprocess.Popen[bytes]] = []
        self.count = 0

    def start(self, command: Command, workdir: Path) -> subprocess.Popen[bytes]:
        self.count += 1
        base = self.logs / f"{command.name}-{self.count}"
        env = environment(self.hidden if command.hide_matplotlib else None)
        with base.with_suffix(".out").open("wb") as stdout, base.with_suffix(".err").open("wb") as stderr:
            proc = subprocess.Popen(
                command.command_line(), cwd=workdir, env=env, stdout=stdout, stderr=stderr, start_new_session=True
            )
        proc.log = base  # type: ignore[attr-defined]
        self.started.append(proc)
        return proc

    def close(self) -> None:
        for proc in self.started:
            if proc.poll() is None:
                with suppress(ProcessLookupError):
                    os.killpg(proc.pid, signal.SIGCONT)
            kill_group(proc)


def output(proc: subprocess.Popen[bytes]) -> tuple[str, str]:
    """The process's standard output and error (once it has ended)."""
    base: Path = proc.log  # type: ignore[attr-defined]
    return base.with_suffix(".out").read_text(errors="replace"), base.with_suffix(".err").read_text(errors="replace")


def group_members(pgid: int) -> list[int]:
    """Live (not zombie) processes of process group ``pgid``."""
    members = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            fields = Path(f"/proc/{entry}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if fields[0] != "Z" and int(fields[2]) == pgid:
            members.append(int(entry))
    return members


def kill_group(proc: subprocess.Popen[bytes]) -> None:
    """SIGKILL the process group of ``proc`` (the command and its workers) and wait until it is gone."""
    with suppress(ProcessLookupError):
        os.killpg(proc.pid, signal.SIGKILL)
    proc.wait(timeout=TIMEOUT)
    deadline = time.monotonic() + 30
    while (members := group_members(proc.pid)) and time.monotonic() < deadline:
        for pid in members:
            with suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
        time.sleep(0.01)
    assert not group_members(proc.pid), f"processes of group {proc.pid} survived SIGKILL"


def run_uninterrupted(processes: Processes, command: Command, workdir: Path) -> Run:
    """Run the command to its end in a fresh ``workdir``; it must exit 0."""
    prepare(command, workdir)
    started = time.monotonic()
    proc = processes.start(command, workdir)
    try:
        proc.wait(timeout=TIMEOUT)
    finally:
        kill_group(proc)
    seconds = time.monotonic() - started
    out, err = output(proc)
    assert proc.returncode == 0, f"{command.name} exited {proc.returncode}: {err}"
    return Run(workdir, seconds, out, err)


def startup_seconds(processes: Processes, workdir: Path, *, repeats: int = 3) -> float:
    """The shortest of ``repeats`` runs of ``energy-margin --version``: the start-up every command pays."""
    version = Command("version", ("--version",), out=".")
    return min(run_uninterrupted(processes, version, workdir / str(run)).seconds for run in range(repeats))


def kill_and_resume(
    processes: Processes,
    command: Command,
    workdir: Path,
    *,
    duration: float,
    seed: int,
    startup: float = 0.3,
    kills: int = 10,
    max_attempts: int = 80,
) -> KillReport:
    """Start the command in a fresh ``workdir`` again and again, SIGKILLing it, then let it finish.

    Each attempt is SIGKILLed (its whole process group) after a time drawn uniformly from
    ``[startup, duration]`` by ``numpy.random.default_rng(seed)`` (``startup``: what starting
    the interpreter and importing the package takes, see :func:`startup_seconds`, so kills fall
    in the command's work rather than in its imports), unless it ended first, in which case it
    must have exited 0 (a rerun of a finished run is a rerun like any other: it opens, checks
    and rewrites the run's files, and is killed in turn). After an attempt ended by itself,
    later times are drawn up to the time it took (what a rerun takes now), from half of it
    where that is shorter than ``startup``: on a fast machine a rerun of a finished run is
    little more than the start-up, and a kill must still be able to land in it. Once ``kills``
    kills landed on a live process, a last rerun runs to its end and must exit 0.
    """
    prepare(command, workdir)
    rng = np.random.default_rng(seed)
    report = KillReport()
    span = duration
    while report.kills < kills:
        assert report.attempts < max_attempts, f"only {report.kills} kills landed in {max_attempts} attempts"
        report.attempts += 1
        earliest = min(startup, 0.5 * span)
        delay = float(rng.uniform(earliest, span))
        started = time.monotonic()
        proc = processes.start(command, workdir)
        try:
            proc.wait(timeout=delay)
        except subprocess.TimeoutExpired:
            pass
        finally:
            kill_group(proc)
        _, err = output(proc)
        report.stderr.append(err)
        if proc.returncode == -signal.SIGKILL:
            report.kills += 1
            report.kill_times.append(round(delay, 3))
        else:
            # Ended before its kill: after a kill, a rerun must resume or finish, never refuse.
            assert proc.returncode == 0, f"attempt {report.attempts} exited {proc.returncode}: {err}"
            report.completed_before_kill += 1
            # The run is complete: a rerun now takes this long; later kills fall inside it.
            span = min(span, time.monotonic() - started)
    started = time.monotonic()
    proc = processes.start(command, workdir)
    try:
        proc.wait(timeout=TIMEOUT)
    finally:
        kill_group(proc)
    report.final_seconds = time.monotonic() - started
    _, err = output(proc)
    assert proc.returncode == 0, f"the last rerun exited {proc.returncode}: {err}"
    assert "Traceback" not in err, err
    return report


# ---------------------------------------------------------------- comparing what two runs wrote


@dataclass
class Comparison:
    """What :func:`compare_trees` compared."""

    files: int = 0
    rows: int = 0  # CSV rows (headers excluded)
    arrays: int = 0  # arrays of .npz archives
    json_files: int = 0
    by_file: dict[str, int] = field(default_factory=dict)  # rows per CSV file


def hidden_entries(root: Path) -> list[str]:
    """Entries under ``root`` whose names start with a dot: temporary files, staging folders, a lock."""
    return sorted(str(p.relative_to(root)) for p in root.rglob(".*"))


def _files(root: Path) -> dict[str, Path]:
    return {str(p.relative_to(root)): p for p in sorted(root.rglob("*")) if p.is_file()}


def _strip_timing(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _strip_timing(v) for k, v in value.items() if k not in TIMING}
    if isinstance(value, list):
        return [_strip_timing(v) for v in value]
    return value


def _csv_table(path: Path) -> tuple[list[str], list[tuple[str, ...]]]:
    """Header and rows of a CSV file, timing columns dropped (cells as written: exact text)."""
    text = path.read_text(encoding="utf-8")
    assert not text or text.endswith("\n"), f"{path} ends inside a row"
    rows = list(csv.reader(io.StringIO(text)))
    header, body = (rows[0], rows[1:]) if rows else ([], [])
    keep = [i for i, name in enumerate(header) if name not in TIMING]
    for number, row in enumerate(body, start=2):
        assert len(row) == len(header), f"{path} line {number} has {len(row)} cells, the header {len(header)}"
    return [header[i] for i in keep], [tuple(row[i] for i in keep) for row in body]


def _compare_npz(reference: Path, result: Path) -> int:
    with np.load(reference, allow_pickle=False) as a, np.load(result, allow_pickle=False) as b:
        assert sorted(a.files) == sorted(b.files), f"{result}: arrays {sorted(b.files)}, expected {sorted(a.files)}"
        for name in a.files:
            x, y = a[name], b[name]
            if x.dtype.kind == y.dtype.kind == "U" and x.ndim == y.ndim == 0 and str(x).startswith("{"):
                # A JSON document stored as an array (an episode's info): timings dropped (and so
                # the string's length, its dtype, may differ).
                a_doc = json.dumps(_strip_timing(json.loads(str(x))), sort_keys=True)
                b_doc = json.dumps(_strip_timing(json.loads(str(y))), sort_keys=True)
                assert b_doc == a_doc, f"{result}:{name} differs:\n{b_doc}\nexpected\n{a_doc}"
                continue
            assert x.dtype == y.dtype and x.shape == y.shape, (
                f"{result}:{name} {y.dtype}{y.shape} != {x.dtype}{x.shape}"
            )
            np.testing.assert_array_equal(y, x, err_msg=f"{result}:{name}", strict=True)
        return len(a.files)


def compare_trees(reference: Path, result: Path, *, ignore: Iterable[str] = ()) -> Comparison:
    """Check that ``result`` holds what ``reference`` holds; return what was compared.

    The same files. CSV: the same header and the same rows in the same order (any order in a
    journal), every cell's text identical but in timing columns (:data:`TIMING`) - so no row is
    missing or duplicated. JSON:
    equal once timing keys are dropped (compared as sorted JSON text: exact floats, NaN included).
    ``.npz``: the same arrays, dtypes, shapes and values. Figures (``.png``): present in both.
    Anything else: identical bytes. Nothing hidden (temporary files, staging folders, a lock file)
    is left in ``result``.
    """
    assert hidden_entries(result) == [], f"left behind in {result}: {hidden_entries(result)}"
    ignored = set(ignore)
    expected = {k: v for k, v in _files(reference).items() if k not in ignored}
    found = {k: v for k, v in _files(result).items() if k not in ignored}
    assert sorted(found) == sorted(expected), f"files differ: {sorted(set(found) ^ set(expected))}"
    comparison = Comparison()
    for name, path in expected.items():
        other = found[name]
        comparison.files += 1
        if path.suffix == ".csv":
            header, rows = _csv_table(path)
            other_header, other_rows = _csv_table(other)
            assert other_header == header, f"{name}: header {other_header}, expected {header}"
            missing = sorted(set(rows) - set(other_rows))
            extra = len(other_rows) - len(set(other_rows))
            assert not missing, f"{name}: {len(missing)} rows missing or different, first {missing[0]}"
            assert extra == len(rows) - len(set(rows)), f"{name}: {extra} duplicated rows"
            if ".journal." in path.name:  # appended as rows finish: in the order workers finished them
                rows, other_rows = sorted(rows), sorted(other_rows)
            assert other_rows == rows, f"{name}: rows differ (order or content)"
            comparison.rows += len(rows)
            comparison.by_file[name] = len(rows)
        elif path.suffix == ".json":
            a = json.dumps(_strip_timing(json.loads(path.read_text())), sort_keys=True)
            b = json.dumps(_strip_timing(json.loads(other.read_text())), sort_keys=True)
            assert b == a, f"{name}: JSON differs:\n{b}\nexpected\n{a}"
            comparison.json_files += 1
        elif path.suffix == ".npz":
            comparison.arrays += _compare_npz(path, other)
        elif path.suffix == ".png":
            assert other.stat().st_size > 0
        else:
            assert other.read_bytes() == path.read_bytes(), f"{name}: bytes differ"
    return comparison


# ---------------------------------------------------------------- a second writer


def lock_holder(directory: Path) -> dict[str, Any] | None:
    """The holder named in ``directory``'s lock file, or ``None`` when there is none (yet)."""
    try:
        holder = json.loads((directory / LOCK_FILE).read_text())
    except (OSError, ValueError):
        return None
    return holder if isinstance(holder, dict) else None


def wait_for_lock(proc: subprocess.Popen[bytes], directory: Path, timeout: float = TIMEOUT) -> bool:
    """Wait until ``proc`` holds ``directory``'s lock (its pid in the lock file); ``False`` if it ended first."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        holder = lock_holder(directory)
        if holder is not None and holder.get("pid") == proc.pid:
            return True
        if proc.poll() is not None:
            return False
        time.sleep(0.002)
    raise AssertionError(f"{directory} was not locked within {timeout} s")
