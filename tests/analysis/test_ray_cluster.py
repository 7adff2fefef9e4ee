"""A Ray cluster as a user starts it, and a node that leaves it in the middle of a run.

`ray start --head` and a second node joining with `ray start --address ...` (both on this
machine, one CPU each), then `energy-margin analyze --executor ray --address ...`: the scores are
the local pool's, exactly. Killing every process of the second node once a few frames are done
(as when a machine is lost) still finishes the run, with every frame scored once. The cluster is
stopped by killing its own processes: ``ray stop`` would stop every Ray cluster of the machine and
programs beside the tests.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.run import analyze
from energy_margin.data.generate import generate_dataset
from energy_margin.data.scores_file import JOURNAL_FILE, load_scores, read_journal

pytestmark = pytest.mark.slow

RAY = Path(sys.executable).with_name("ray")
DETERMINISTIC = ("trajectory", "frame", "capture_score", "success_score", "nodes", "expansions", "seed")
# The tree's own score by name: the trees alone, the quickest rows to reach the journal.
CONFIG = AnalyzerConfig(expansions=400, continuation=0)
SEED = 3


def _environment() -> dict[str, str]:
    return {**os.environ, "RAY_USAGE_STATS_ENABLED": "0", "RAY_AUTH_MODE": "disabled"}


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def _processes() -> dict[int, tuple[bytes, int]]:
    """Every process's command line (its arguments joined by spaces) and parent pid, by pid."""
    found = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            command = (entry / "cmdline").read_bytes().replace(b"\0", b" ")
            # The fields after the command name, which is in parentheses and may hold spaces.
            parent = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
        except (OSError, IndexError, ValueError):
            continue
        found[int(entry.name)] = (command, parent)
    return found


def _ray_processes() -> set[int]:
    return {pid for pid, (command, _) in _processes().items() if b"ray" in command}


def _cluster_processes(temp_dir: Path) -> set[int]:
    """The processes of the cluster started in ``temp_dir``: those naming it, and all their descendants.

    Ray's agents and workers rename their command lines (``ray::IDLE``); they are the raylet's children.
    """
    processes = _processes()
    found = {pid for pid, (command, _) in processes.items() if str(temp_dir).encode() in command}
    grown = True
    while grown:
        children = {pid for pid, (_, parent) in processes.items() if parent in found} - found
        found |= children
        grown = bool(children)
    return found - {os.getpid()}


def _stop_cluster(temp_dir: Path) -> None:
    """Stop the cluster started in ``temp_dir`` and nothing else.

    ``ray stop`` would stop every Ray process of the machine, and every process whose command line
    holds one of the names it looks for (``monitor.py`` among them): a user's own cluster and
    programs running beside the tests.
    """
    for signal_number in (signal.SIGTERM, signal.SIGKILL):
        for pid in _cluster_processes(temp_dir):
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.kill(pid, signal_number)
        deadline = time.monotonic() + 10
        while _cluster_processes(temp_dir) and time.monotonic() < deadline:
            time.sleep(0.2)


def _ray(*args: str) -> None:
    subprocess.run([str(RAY), *args], env=_environment(), check=True, capture_output=True, timeout=120)


@pytest.fixture
def cluster() -> Iterator[tuple[str, set[int]]]:
    """A head node and a second node (one CPU each); yields the address and the second node's pids."""
    pytest.importorskip("ray")
    if not RAY.exists():
        pytest.skip(f"no `ray` command beside {sys.executable}")
    port = _free_port()
    address = f"127.0.0.1:{port}"
    # A short folder of its own (Ray's socket paths must stay under about 100 bytes): the cluster's
    # processes name it, so that only they are stopped afterwards.
    temp_dir = Path(tempfile.mkdtemp(prefix="emray", dir="/tmp"))
    try:
        _ray(
            "start", "--head", f"--port={port}", "--num-cpus=1", "--include-dashboard=false", "--disable-usage-stats",
            f"--temp-dir={temp_dir}",
        )  # fmt: skip
        before = _ray_processes()
        _ray("start", f"--address={address}", "--num-cpus=1", "--disable-usage-stats")
        # Every process that appeared with the second node belongs to it (raylet, its workers' parent...).
        second = _ray_processes() - before
        yield address, second
    finally:
        _stop_cluster(temp_dir)
        shutil.rmtree(temp_dir, ignore_errors=True)


def test_stopping_the_cluster_spares_other_processes(tmp_path: Path) -> None:
    """The teardown stops the cluster's processes only: not a program whose command line holds ``monitor.py``."""
    bystander_script = tmp_path / "monitor.py"
    bystander_script.write_text("import time\ntime.sleep(600)\n")
    bystander = subprocess.Popen([sys.executable, str(bystander_script)])
    temp_dir = Path(tempfile.mkdtemp(prefix="emray", dir="/tmp"))
    try:
        child_script = tmp_path / "child.py"
        child_script.write_text("import time\ntime.sleep(600)\n")
        # A stand-in for a cluster process (it names the folder) with a child that does not.
        member = subprocess.Popen(
            [sys.executable, "-c", "import subprocess, sys, time; subprocess.Popen([sys.executable, sys.argv[1]]); "
             "time.sleep(600)", str(child_script), str(temp_dir)]
        )  # fmt: skip
        deadline = time.monotonic() + 30
        while len(_cluster_processes(temp_dir)) < 2 and time.monotonic() < deadline:
            time.sleep(0.1)
        members = _cluster_processes(temp_dir)
        assert member.pid in members and len(members) == 2
        assert bystander.pid not in members
        _stop_cluster(temp_dir)
        assert member.wait(timeout=30) != 0
        assert not _cluster_processes(temp_dir)
        assert bystander.poll() is None
    finally:
        bystander.kill()
        bystander.wait()
        shutil.rmtree(temp_dir, ignore_errors=True)


def _table(directory: Path) -> list[tuple]:
    scores = load_scores(directory)
    return sorted(zip(*(scores[c].tolist() for c in DETERMINISTIC), strict=True))


def test_a_lost_node_loses_no_frame(tmp_path: Path, cluster: tuple[str, set[int]]) -> None:
    address, second_node = cluster
    assert second_node, "the second node started no process"
    source = tmp_path / "data"
    generate_dataset("pushing", n_objects=4, n_trajectories=4, n_frames=4, seed=1, out=source)
    local = tmp_path / "local"
    shutil.copytree(source, local)
    analyze(local, CONFIG, seed=SEED, workers=2, progress=False)

    on_cluster = tmp_path / "cluster"
    shutil.copytree(source, on_cluster)
    command = [
        sys.executable,
        "-m",
        "energy_margin",
        "analyze",
        str(on_cluster),
        "--expansions",
        str(CONFIG.expansions),
        "--seed",
        str(SEED),
        "--workers",
        "2",
        "--executor",
        "ray",
        "--address",
        address,
        "--continuation",
        "0",
        "--no-progress",
    ]
    process = subprocess.Popen(command, env=_environment(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    journal = on_cluster / JOURNAL_FILE
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and process.poll() is None:
        if journal.exists() and len(read_journal(journal)) >= 2:
            break
        time.sleep(0.1)
    done_before = len(read_journal(journal)) if journal.exists() else 0
    assert process.poll() is None, "the run ended before the node could be stopped"
    for pid in second_node:
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGKILL)
    _, err = process.communicate(timeout=600)
    assert process.returncode == 0, err
    assert done_before < 16
    assert _table(on_cluster) == _table(local)
    lines = journal.read_text().splitlines()
    assert len(lines) == 1 + 16  # header and one line per frame: none lost, none twice
