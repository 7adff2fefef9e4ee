"""Fixtures of the fault tests: the five long commands on their smallest workloads, run for real."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from fault_harness import Command, Processes, Run, hidden_matplotlib, run_uninterrupted, startup_seconds


def commands(dataset: Path) -> dict[str, Command]:
    """The long commands, each on a workload of one to two seconds, about a third of it the imports."""
    return {
        # 2 trajectories x 3 frames of 2 objects, two worker processes (killed with their parent).
        "analyze": Command(
            "analyze",
            ("analyze", "data", "--expansions", "2000", "--no-progress", "--workers", "2"),
            out="data",
            inputs={"data": dataset},
        ),
        # Two copies of the same 6 frames, each overlap rejected by simulation (the default protocol).
        "perturb": Command(
            "perturb",
            ("perturb", "data", "--repeats", "2", "--seed", "1", "--out", "copies", "--no-progress"),
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
                "--expansions",
                "3",
                "--methods",
                "est",
                "montecarlo",
                "--lambdas",
                "1",
                "5",
                "--lambda-expansions",
                "3",
                "--bootstrap",
                "20",
                "--seed",
                "2",
            ),
            out="out",
        ),
        # Two pusher widths, 2 trajectories x 2 frames of 2 objects, 200 expansions a frame.
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
                "--expansions",
                "200",
                "--bootstrap",
                "20",
                "--out",
                "out",
                "--no-progress",
            ),
            out="out",
        ),
        # Eight 1 s episodes of 2 objects, a small MPPI, 20 expansions per recorded frame.
        "control": Command(
            "control",
            (
                "control",
                "--task",
                "pushing",
                "--objects",
                "2",
                "--episodes",
                "8",
                "--disturbance",
                "hard",
                "--seed",
                "3",
                "--frames",
                "3",
                "--expansions",
                "20",
                "--samples",
                "16",
                "--horizon",
                "5",
                "--period",
                "0.05",
                "--set",
                "duration=1.0",
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
def startup(tmp_path_factory: pytest.TempPathFactory, hidden: Path) -> Iterator[float]:
    """Seconds that starting ``energy-margin`` takes on this machine, now (the kills fall after it)."""
    runner = Processes(tmp_path_factory.mktemp("startup-logs"), hidden)
    yield startup_seconds(runner, tmp_path_factory.mktemp("startup"))
    runner.close()


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
