"""Fixtures of the fault tests: the five long commands on their smallest workloads, run for real."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from fault_harness import Command, Processes, Run, hidden_matplotlib, run_uninterrupted


def commands(dataset: Path) -> dict[str, Command]:
    """The long commands, each on a workload of a few seconds (most of it the imports)."""
    return {
        # 2 trajectories x 3 frames of 2 objects, two worker processes (killed with their parent).
        "analyze": Command(
            "analyze",
            ("analyze", "data", "--iterations", "200", "--no-progress", "--workers", "2"),
            out="data",
            inputs={"data": dataset},
        ),
        # Three copies of the same 6 frames (the paper protocol: no rejection simulation).
        "perturb": Command(
            "perturb",
            ("perturb", "data", "--repeats", "3", "--seed", "1", "--out", "copies", "--protocol", "paper"),
            out="copies",
            inputs={"data": dataset},
        ),
        # One task, 2 x 2 frames, two methods and a two-lambda sweep at 3 expansions a frame.
        "study": Command(
            "study",
            (
                "study",
                "out",
                "--tasks",
                "pushing",
                "--trajectories",
                "2",
                "--frames",
                "2",
                "--budgets",
                "3",
                "--methods",
                "est",
                "montecarlo",
                "--lambdas",
                "1",
                "5",
                "--lambda-budget",
                "3",
                "--bootstrap",
                "20",
                "--seed",
                "2",
            ),
            out="out",
        ),
        # Two pusher widths, 2 trajectories x 2 frames of 2 objects, 8 expansions a frame.
        "sweep": Command(
            "sweep",
            (
                "sweep",
                "--task",
                "pushing",
                "--param",
                "pusher_width=0.6,0.8",
                "--trajectories",
                "2",
                "--frames",
                "2",
                "--objects",
                "2",
                "--seed",
                "3",
                "--iterations",
                "8",
                "--bootstrap",
                "20",
                "--out",
                "out",
                "--no-progress",
            ),
            out="out",
        ),
        # Four short episodes of 2 objects, a tiny MPPI, 2 expansions per recorded frame.
        "control": Command(
            "control",
            (
                "control",
                "--task",
                "pushing",
                "--objects",
                "2",
                "--episodes",
                "4",
                "--disturbance",
                "hard",
                "--seed",
                "3",
                "--frames",
                "3",
                "--score-expansions",
                "2",
                "--samples",
                "3",
                "--horizon",
                "2",
                "--period",
                "0.05",
                "--set",
                "duration=0.3",
                "--out",
                "out",
                "--no-progress",
            ),
            out="out",
        ),
    }


@pytest.fixture(scope="session")
def fault_commands(tiny_dataset_source: Path) -> dict[str, Command]:
    return commands(tiny_dataset_source)


@pytest.fixture(scope="session")
def hidden(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return hidden_matplotlib(tmp_path_factory.mktemp("hidden"))


@pytest.fixture
def processes(tmp_path: Path, hidden: Path) -> Iterator[Processes]:
    """Starts commands; whatever is left of them is killed afterwards."""
    started = Processes(tmp_path / "logs", hidden)
    yield started
    started.close()


@pytest.fixture(scope="session")
def references(tmp_path_factory: pytest.TempPathFactory, hidden: Path) -> Iterator[Callable[[Command], Run]]:
    """An uninterrupted run of a command (run once per session, when first asked for)."""
    done: dict[str, Run] = {}
    runner = Processes(tmp_path_factory.mktemp("reference-logs"), hidden)

    def reference(command: Command) -> Run:
        if command.name not in done:
            done[command.name] = run_uninterrupted(runner, command, tmp_path_factory.mktemp(command.name) / "work")
        return done[command.name]

    yield reference
    runner.close()
