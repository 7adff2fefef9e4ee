"""An exclusive lock on a run directory, held by one writing process.

The lock is a POSIX record lock (``fcntl.lockf``) on ``DIR/.energy-margin.lock``, whose content
names the holder (process id, host, command, start time). The kernel releases a record lock when
its process ends, however it ends, and a forked worker does not inherit it, so a lock file left by
a killed process is free again and is taken over by the next writer; a live writer's lock refuses
a second writer with one line naming the first.
"""

from __future__ import annotations

import errno
import fcntl
import json
import os
import socket
import sys
import time
from pathlib import Path
from typing import Any

from energy_margin.errors import EnergyMarginError

__all__ = [
    "LOCK_FILE",
    "RunLock",
    "RunLockedError",
]

LOCK_FILE = ".energy-margin.lock"


class RunLockedError(EnergyMarginError):
    """Another live process holds the run directory's lock."""


class RunLock:
    """The exclusive writer's lock of ``directory`` (a context manager).

    Args:
        directory: the run directory (it must exist).

    Attributes:
        path: the lock file.
        taken_over: the holder named in a lock file left by an ended process, if any.

    """

    def __init__(self, directory: Path | str) -> None:
        self.path = Path(directory) / LOCK_FILE
        self.taken_over: dict[str, Any] | None = None
        self._fd: int | None = None

    def acquire(self) -> RunLock:
        """Take the lock or raise :class:`RunLockedError` naming the live holder."""
        if self._fd is not None:
            return self
        while True:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
            try:
                fcntl.lockf(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError as error:
                os.close(fd)
                if error.errno not in (errno.EACCES, errno.EAGAIN):
                    raise EnergyMarginError(f"cannot lock {self.path.parent}: {error.strerror}") from None
                raise RunLockedError(self._refusal()) from None
            # A releasing holder unlinks the file before it unlocks: a lock on an unlinked file
            # guards nothing, so start again on the file now at the path.
            try:
                same = os.fstat(fd).st_ino == os.stat(self.path).st_ino
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)
        previous = _read_holder(fd)
        self.taken_over = previous or None
        holder = {
            "pid": os.getpid(),
            "host": socket.gethostname(),
            "command": " ".join(sys.argv),
            "started": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        }
        os.ftruncate(fd, 0)
        os.pwrite(fd, (json.dumps(holder) + "\n").encode(), 0)
        self._fd = fd
        return self

    def release(self) -> None:
        """Remove the lock file and release the lock (idempotent)."""
        if self._fd is None:
            return
        self.path.unlink(missing_ok=True)
        os.close(self._fd)  # closing releases the record lock
        self._fd = None

    @property
    def held(self) -> bool:
        """Whether this object holds the lock."""
        return self._fd is not None

    def _refusal(self) -> str:
        try:
            holder = json.loads(self.path.read_text(encoding="utf-8") or "{}")
        except (OSError, ValueError):
            holder = {}
        if not isinstance(holder, dict):
            holder = {}
        who = f"process {holder.get('pid', '?')} on {holder.get('host', '?')}"
        since = f" since {holder['started']}" if holder.get("started") else ""
        return f"{self.path.parent} is being written by {who}{since}; wait for it to finish or choose another `out`"

    def __enter__(self) -> RunLock:
        return self.acquire()

    def __exit__(self, *exc: object) -> None:
        self.release()


def _read_holder(fd: int) -> dict[str, Any]:
    try:
        text = os.pread(fd, 4096, 0).decode("utf-8", errors="replace")
        holder = json.loads(text) if text.strip() else {}
    except ValueError:
        return {}
    return holder if isinstance(holder, dict) else {}
