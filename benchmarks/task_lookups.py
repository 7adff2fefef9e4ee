"""How often a command looks its task up by name again, and from which modules.

A task is meant to be resolved once, where a command starts, and passed on as an object. This
runs ``generate``, ``analyze`` and ``design`` on tiny settings in this process, with a profile hook
that counts every call of the task registry's lookups (``energy_margin.tasks.get_task``,
``task_class``, ``get_recorded_task``, ``resolve_task``) from outside ``energy_margin.tasks``, by
the module that called it, and prints one table per command.

    python benchmarks/task_lookups.py --out docs/figures/task_lookups.json
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import sys
import tempfile
from collections import Counter
from pathlib import Path
from types import FrameType
from typing import Any

from energy_margin import tasks
from energy_margin.cli import main as cli_main

#: The lookups by name (``resolve_task`` is absent from releases before it, which this also measures).
LOOKUPS = {
    getattr(tasks, name).__code__
    for name in ("get_task", "task_class", "get_recorded_task", "resolve_task")
    if hasattr(tasks, name)
}
TINY = ["--objects", "2", "--trajectories", "2", "--frames", "3", "--seed", "1"]


def count_lookups(argv: list[str]) -> Counter[str]:
    """Run ``energy-margin ARGV`` and count the registry lookups by calling module."""
    calls: Counter[str] = Counter()

    def profile(frame: FrameType, event: str, arg: Any) -> None:
        del arg
        if event == "call" and frame.f_code in LOOKUPS and frame.f_back is not None:
            # resolve_task given a task object builds no task from a name: not a lookup.
            by_name = not isinstance(frame.f_locals.get("task"), tasks.Task)
            caller = frame.f_back.f_globals.get("__name__", "?")
            if caller != "energy_margin.tasks" and by_name:
                calls[caller] += 1

    sys.setprofile(profile)
    try:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            status = cli_main(argv)
    finally:
        sys.setprofile(None)
    if status != 0:
        raise SystemExit(f"energy-margin {' '.join(argv)} exited {status}")
    return calls


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--out", type=Path, help="write the counts as JSON here")
    args = parser.parse_args()
    results: dict[str, dict[str, int]] = {}
    with tempfile.TemporaryDirectory() as work:
        data = str(Path(work) / "data")
        commands = {
            "generate": ["generate", "--task", "pushing", *TINY, "--out", data],
            "analyze": ["analyze", data, "--expansions", "10", "--seed", "1"],
            "design": [
                "design",
                "--task",
                "pushing",
                "--param",
                "pusher_width=0.4:1.0",
                "--optimizer",
                "grid",
                "--evaluations",
                "2",
                "--verify",
                "1",
                "--expansions",
                "10",
                *TINY,
                "--out",
                str(Path(work) / "design"),
            ],
        }
        for name, argv in commands.items():
            calls = count_lookups(argv)
            results[name] = dict(calls.most_common())
            print(f"{name}: {sum(calls.values())} lookups of the task by name from {len(calls)} modules")
            for module, count in calls.most_common():
                print(f"  {count:>5}  {module}")
    if args.out:
        args.out.write_text(json.dumps(results, indent=2) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
