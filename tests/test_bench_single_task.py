"""benchmarks/single_task.py: the page's commands, and the same with another seed."""

from __future__ import annotations

import pytest

from bench_modules import load_benchmark


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("single_task")


def test_seed_zero_is_the_pages_commands(bench) -> None:
    assert bench.seeded(bench.COMMANDS, 0) == list(bench.COMMANDS)


def test_another_seed_reaches_generation_and_both_analyses(bench) -> None:
    commands = bench.seeded(bench.COMMANDS, 2)
    tree = bench.seeded(bench.TREE_SUCCESS, 2)
    assert "--seed 2" in commands[0] and commands[0].startswith("energy-margin generate")
    assert "--seed 2" in commands[1] and "--seed 2" in tree[0]
    assert not any("--seed 0" in command for command in commands + tree)
    assert commands[2] == bench.COMMANDS[2]


def test_a_cost_model_reaches_both_analyses_only(bench) -> None:
    commands = bench.seeded(bench.COMMANDS, 0, "energy")
    tree = bench.seeded(bench.TREE_SUCCESS, 0, "energy")
    assert commands[1].endswith("--cost energy") and tree[0].endswith("--cost energy")
    assert "--cost" not in commands[0] and "--cost" not in commands[2] and "--cost" not in tree[1]
