"""The writer's lock of a run directory: a live holder refuses, an ended one's lock is taken over."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from energy_margin.runs.lock import LOCK_FILE, RunLock, RunLockedError

HOLD = """
import sys, time
from energy_margin.runs.lock import RunLock
lock = RunLock(sys.argv[1]).acquire()
print("held", flush=True)
time.sleep(float(sys.argv[2]))
"""


def _holder(directory: Path, seconds: float = 30.0) -> subprocess.Popen[str]:
    proc = subprocess.Popen(
        [sys.executable, "-c", HOLD, str(directory), str(seconds)], stdout=subprocess.PIPE, text=True
    )
    assert proc.stdout is not None and proc.stdout.readline().strip() == "held"
    return proc


def test_a_second_writer_is_refused_naming_the_first(tmp_path: Path) -> None:
    proc = _holder(tmp_path)
    try:
        with pytest.raises(RunLockedError) as caught:
            RunLock(tmp_path).acquire()
        message = str(caught.value)
        assert "\n" not in message
        assert f"is being written by process {proc.pid} on {socket.gethostname()}" in message
    finally:
        proc.kill()
        proc.wait()


def test_the_lock_of_a_killed_process_is_taken_over(tmp_path: Path) -> None:
    proc = _holder(tmp_path)
    proc.kill()
    proc.wait()
    assert (tmp_path / LOCK_FILE).exists()  # SIGKILL left the file
    lock = RunLock(tmp_path).acquire()
    try:
        assert lock.taken_over is not None and lock.taken_over["pid"] == proc.pid
        assert json.loads((tmp_path / LOCK_FILE).read_text())["pid"] == os.getpid()
    finally:
        lock.release()
    assert not (tmp_path / LOCK_FILE).exists()


def test_a_lock_file_naming_a_dead_process_is_taken_over(tmp_path: Path) -> None:
    (tmp_path / LOCK_FILE).write_text(json.dumps({"pid": 999_999_999, "host": "elsewhere"}) + "\n")
    with RunLock(tmp_path) as lock:
        assert lock.held and lock.taken_over == {"pid": 999_999_999, "host": "elsewhere"}


def test_forked_children_do_not_keep_the_lock(tmp_path: Path) -> None:
    lock = RunLock(tmp_path).acquire()
    child = os.fork()
    if child == 0:  # the child outlives the parent's hold on the lock for a while
        time.sleep(3.0)
        os._exit(0)
    try:
        lock.release()
        with RunLock(tmp_path) as again:
            assert again.held
    finally:
        os.kill(child, 9)
        os.waitpid(child, 0)


def test_release_is_idempotent_and_the_lock_can_be_taken_again(tmp_path: Path) -> None:
    lock = RunLock(tmp_path).acquire()
    assert lock.acquire() is lock  # taking a held lock again is a no-op
    lock.release()
    lock.release()
    assert not lock.held and not (tmp_path / LOCK_FILE).exists()
    with RunLock(tmp_path) as again:
        assert again.held and again.taken_over is None
