"""Two writers of one output directory: the second is refused in one line naming the first, which finishes unharmed."""

from __future__ import annotations

import os
import signal
import subprocess
from collections.abc import Callable
from pathlib import Path

import pytest
from fault_harness import TIMEOUT, Command, Processes, Run, compare_trees, output, prepare, wait_for_lock


@pytest.mark.slow
@pytest.mark.parametrize("name", ["analyze", "perturb", "study", "sweep", "control"])
def test_a_second_writer_is_refused_and_the_first_finishes(
    name: str,
    fault_commands: dict[str, Command],
    references: Callable[[Command], Run],
    processes: Processes,
    tmp_path: Path,
) -> None:
    command = fault_commands[name]
    reference = references(command)
    workdir = prepare(command, tmp_path / "work")
    first = processes.start(command, workdir)
    assert wait_for_lock(first, workdir / command.out), f"{name} ended without locking {command.out}"
    # Hold the first writer where it is (lock taken, results not all written): however fast the
    # machine, the second one meets a live writer. The kernel keeps a stopped process's lock.
    os.killpg(first.pid, signal.SIGSTOP)
    try:
        second = processes.start(command, workdir)
        second.wait(timeout=TIMEOUT)
        out, err = output(second)
    finally:
        os.killpg(first.pid, signal.SIGCONT)
    assert second.returncode == 2, (second.returncode, err)
    assert out == ""
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("energy-margin: error: "), err
    assert f"is being written by process {first.pid} on " in lines[0], err
    try:
        first.wait(timeout=TIMEOUT)
    except subprocess.TimeoutExpired:
        pytest.fail(f"the first {name} did not finish")
    assert first.returncode == 0, output(first)[1]
    compare_trees(reference.out(command), workdir / command.out)
