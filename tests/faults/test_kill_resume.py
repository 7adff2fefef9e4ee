"""Each long command SIGKILLed ten or more times at seeded random moments, resumed: it writes what one run does."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest
from fault_harness import Command, Processes, Run, compare_trees, kill_and_resume

# A fixed seed per command: the kill times are the same draws from run to run (over the
# duration measured in the test, so the moments they hit follow the machine's speed).
SEEDS = {"analyze": 11, "perturb": 12, "study": 13, "sweep": 14, "control": 15}
KILLS = 10

# What the uninterrupted runs hold, so that a comparison that compares nothing cannot pass.
EXPECTED_ROWS = {
    "analyze": {"scores.csv": 6, "scores.journal.csv": 6},
    "study": {"study.csv": 5, "study_differences.csv": 3, "study_lambda.csv": 2, "pushing/runs/est-3/scores.csv": 4},
    "sweep": {"results.csv": 2, "designs/pusher_width-0.6/scores.csv": 4, "designs/pusher_width-0.8/scores.csv": 4},
}
EXPECTED_FILES = {
    "perturb": ["1/dataset.json", "1/frames.npz", "2/dataset.json", "2/frames.npz"],
    "control": ["control.json", "dataset.json", "frames.npz", *(f"episodes/{i:05d}.npz" for i in range(8))],
}


@pytest.mark.slow
@pytest.mark.parametrize("name", list(SEEDS))
def test_killed_ten_times_then_resumed_writes_what_an_uninterrupted_run_writes(
    name: str,
    fault_commands: dict[str, Command],
    references: Callable[[Command], Run],
    processes: Processes,
    startup: float,
    tmp_path: Path,
) -> None:
    command = fault_commands[name]
    reference = references(command)  # how long the command takes on this machine, now
    report = kill_and_resume(
        processes, command, tmp_path / "work", duration=reference.seconds, startup=startup, seed=SEEDS[name]
    )
    assert report.kills >= KILLS, report
    out = tmp_path / "work" / command.out
    comparison = compare_trees(reference.out(command), out)
    for file, rows in EXPECTED_ROWS.get(name, {}).items():
        assert comparison.by_file[file] == rows, (file, comparison.by_file)
    for file in EXPECTED_FILES.get(name, []):
        assert (out / file).is_file(), file
    print(
        f"\n{name}: start-up {startup:.2f} s, uninterrupted {reference.seconds:.1f} s; "
        f"{report.kills} kills landed in {report.attempts} attempts "
        f"({report.completed_before_kill} finished before their kill) at {report.kill_times} s; last rerun "
        f"{report.final_seconds:.1f} s; compared {comparison.files} files, {comparison.rows} CSV rows, "
        f"{comparison.arrays} arrays, {comparison.json_files} JSON files"
    )
