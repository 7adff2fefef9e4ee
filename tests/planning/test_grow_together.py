"""Trees grown in lockstep are the trees grown alone: each round of every tree is one batched call."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from energy_margin.data.dataset import load_dataset
from energy_margin.errors import InvalidParameterError
from energy_margin.planning import TreeBudget, grow_tree, grow_trees_together
from energy_margin.planning.costs import make_cost_model


def _inputs(path: Path):  # type: ignore[no-untyped-def]
    dataset = load_dataset(path)
    friction = float(dataset.arrays["friction"][0])
    drive = dataset.arrays["drive"][0]
    roots = [dataset.frame(0, frame) for frame in range(dataset.n_frames)]
    times = [float(dataset.arrays["frame_time"][0, frame]) for frame in range(dataset.n_frames)]
    return dataset.task, friction, drive, roots, times


@pytest.mark.parametrize("method", ["est", "montecarlo"])
def test_lockstep_trees_are_the_trees_grown_alone(tiny_dataset_source: Path, method: str) -> None:
    task, friction, drive, roots, times = _inputs(tiny_dataset_source)
    options = {"budget": TreeBudget(expansions=40), "cost_model": make_cost_model("wrench"), "batch": 6}
    alone = []
    for seed, (root, start) in enumerate(zip(roots, times, strict=True)):
        simulator = task.make_simulator(2, friction, drive)
        rng = np.random.default_rng(seed)
        alone.append(grow_tree(simulator, task, root, drive, rng, start_time=start, method=method, **options))
    together = grow_trees_together(
        task.make_simulator(2, friction, drive),
        task,
        roots,
        drive,
        [np.random.default_rng(seed) for seed in range(len(roots))],
        start_times=times,
        method=method,
        **options,
    )
    for one, other in zip(alone, together, strict=True):
        assert other.expansions == one.expansions == 40
        np.testing.assert_array_equal(other.costs, one.costs)
        np.testing.assert_array_equal(other.object_pos, one.object_pos)
        np.testing.assert_array_equal(other.parents, one.parents)
    # Frames differ, so the trees do: the lockstep did not hand one tree's outcomes to another.
    assert not np.array_equal(together[0].object_pos[1:], together[1].object_pos[1:])
    assert sum(field.physics_s for field in together) > 0


def test_each_tree_stops_on_its_own_rule(tiny_dataset_source: Path) -> None:
    task, friction, drive, roots, times = _inputs(tiny_dataset_source)
    seen: list[int] = []

    def stop_early(field) -> bool:  # type: ignore[no-untyped-def]
        seen.append(field.expansions)
        return field.expansions >= 10

    fields = grow_trees_together(
        task.make_simulator(2, friction, drive),
        task,
        roots[:2],
        drive,
        [np.random.default_rng(0), np.random.default_rng(1)],
        budget=TreeBudget(expansions=40),
        cost_model=make_cost_model("wrench"),
        start_times=times[:2],
        batch=5,
        stops=[stop_early, None],
        check_every=5,
    )
    assert [field.expansions for field in fields] == [10, 40]
    assert seen == [5, 10]


def test_lockstep_growth_refuses_what_it_cannot_do(tiny_dataset_source: Path) -> None:
    task, friction, drive, roots, times = _inputs(tiny_dataset_source)
    simulator = task.make_simulator(2, friction, drive)
    options = {"budget": TreeBudget(expansions=10), "cost_model": make_cost_model("wrench")}
    with pytest.raises(InvalidParameterError, match="batch"):
        grow_trees_together(simulator, task, roots, drive, [np.random.default_rng(0)] * 3, start_times=times,
                            batch=1, **options)  # fmt: skip
    with pytest.raises(InvalidParameterError, match="one entry per root"):
        grow_trees_together(simulator, task, roots, drive, [np.random.default_rng(0)], start_times=times,
                            batch=4, **options)  # fmt: skip
