"""Where a report came from: package version, git commit, engines, machine, command, stage times.

The engine versions are :func:`energy_margin.runs.versions.engine_versions`, the record of every
dataset and run.
"""

from __future__ import annotations

import os
import platform
import subprocess
from pathlib import Path
from typing import Any

from energy_margin._version import __version__
from energy_margin.runs.versions import engine_versions

__all__ = [
    "git_commit",
    "machine",
    "provenance",
]


def git_commit(directory: Path | None = None) -> str | None:
    """The commit of the git checkout holding the package (``+ changes`` when it is modified), or ``None``."""
    directory = directory if directory is not None else Path(__file__).resolve().parent
    try:
        commit = subprocess.run(
            ["git", "-C", str(directory), "rev-parse", "HEAD"], capture_output=True, text=True, timeout=10, check=True
        ).stdout.strip()
        status = subprocess.run(
            ["git", "-C", str(directory), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True,
            text=True,
            timeout=10,
            check=True,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return f"{commit} + uncommitted changes" if status else commit


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as info:
            for line in info:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _memory_gib() -> float | None:
    try:
        with open("/proc/meminfo", encoding="utf-8") as info:
            for line in info:
                if line.startswith("MemTotal:"):
                    return int(line.split()[1]) / 2**20
    except (OSError, ValueError):
        pass
    return None


def machine() -> str:
    """One line: CPU model, cores the process may use, memory, operating system, Python."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    memory = _memory_gib()
    memory_text = f", {memory:.0f} GiB memory" if memory is not None else ""
    return (
        f"{_cpu_model()}, {cores} core(s){memory_text}; {platform.system()} {platform.release()}; "
        f"Python {platform.python_version()}"
    )


def provenance(*, engine: str, command: str, stages: list[dict[str, Any]], total_s: float) -> dict[str, Any]:
    """Everything the report's provenance block shows.

    Args:
        engine: the physics engine of the run.
        command: the command line that produced the report.
        stages: ``{"stage": name, "seconds": wall time, "resumed": bool}`` per stage, in order.
        total_s: wall time of the whole run, s.

    """
    return {
        "package_version": __version__,
        "git_commit": git_commit(),
        "engines": engine_versions(engine),
        "machine": machine(),
        "command": command,
        "stages": stages,
        "total_s": total_s,
    }
