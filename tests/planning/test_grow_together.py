"""Trees grown in lockstep are the trees grown alone: each round of every tree is one batched call."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from energy_margin.data.dataset import load_dataset
from energy_margin.errors import InvalidParameterError
from energy_margin.planning import TreeBudget, grow_tree, grow_trees_together
from energy_margin.planning.costs import make_cost_model


def _frames(path: Path):  # type: ignore[no-untyped-def]
    """Every frame of the tiny set: (root, start time, friction, drive), roll-out by roll-out."""
    dataset = load_dataset(path)
    arrays = dataset.arrays
    frames = [
        (dataset.frame(t, f), float(arrays["frame_time"][t, f]), float(arrays["friction"][t]), arrays["drive"][t])
        for t in range(dataset.n_trajectories)
        for f in range(dataset.n_frames)
    ]
    return dataset.task, frames


@pytest.mark.parametrize("method", ["est", "montecarlo"])
def test_lockstep_trees_are_the_trees_grown_alone(tiny_dataset_source: Path, method: str) -> None:
    task, frames = _frames(tiny_dataset_source)
    # Both roll-outs of the set (two frictions, two drives), one simulator per roll-out.
    assert len({friction for _, _, friction, _ in frames}) == 2
    options = {"budget": TreeBudget(expansions=40), "cost_model": make_cost_model("wrench"), "batch": 6}
    alone = []
    for seed, (root, start, friction, drive) in enumerate(frames):
        simulator = task.make_simulator(2, friction, drive)
        rng = np.random.default_rng(seed)
        alone.append(grow_tree(simulator, task, root, drive, rng, start_time=start, method=method, **options))
    per_roll_out = {friction: task.make_simulator(2, friction, drive) for _, _, friction, drive in frames}
    together = grow_trees_together(
        [per_roll_out[friction] for _, _, friction, _ in frames],
        task,
        [root for root, _, _, _ in frames],
        [drive for _, _, _, drive in frames],
        [np.random.default_rng(seed) for seed in range(len(frames))],
        start_times=[start for _, start, _, _ in frames],
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


def test_rows_run_on_their_own_roll_out_s_model(tiny_dataset_source: Path) -> None:
    """Propagated on another roll-out's simulator, each row still gets its own friction."""
    task, frames = _frames(tiny_dataset_source)
    (root, start, friction, drive), other = frames[0], frames[-1]
    options = {"budget": TreeBudget(expansions=30), "cost_model": make_cost_model("wrench"), "batch": 5}
    simulator = task.make_simulator(2, friction, drive)
    alone = grow_tree(simulator, task, root, drive, np.random.default_rng(0), start_time=start, **options)
    elsewhere = task.make_simulator(2, other[2], other[3])
    together = grow_trees_together([simulator], task, [root], [drive], [np.random.default_rng(0)], start_times=[start],
                                   propagating=elsewhere, **options)  # fmt: skip
    np.testing.assert_array_equal(together[0].object_pos, alone.object_pos)


def test_each_tree_stops_on_its_own_rule(tiny_dataset_source: Path) -> None:
    task, frames = _frames(tiny_dataset_source)
    seen: list[int] = []

    def stop_early(field) -> bool:  # type: ignore[no-untyped-def]
        seen.append(field.expansions)
        return field.expansions >= 10

    simulator = task.make_simulator(2, frames[0][2], frames[0][3])
    fields = grow_trees_together(
        [simulator, simulator],
        task,
        [frames[0][0], frames[1][0]],
        [frames[0][3], frames[1][3]],
        [np.random.default_rng(0), np.random.default_rng(1)],
        budget=TreeBudget(expansions=40),
        cost_model=make_cost_model("wrench"),
        start_times=[frames[0][1], frames[1][1]],
        batch=5,
        stops=[stop_early, None],
        check_every=5,
    )
    assert [field.expansions for field in fields] == [10, 40]
    assert seen == [5, 10]


def test_lockstep_growth_refuses_what_it_cannot_do(tiny_dataset_source: Path) -> None:
    task, frames = _frames(tiny_dataset_source)
    simulator = task.make_simulator(2, frames[0][2], frames[0][3])
    roots = [root for root, _, _, _ in frames[:3]]
    times = [start for _, start, _, _ in frames[:3]]
    drives = [drive for _, _, _, drive in frames[:3]]
    options = {"budget": TreeBudget(expansions=10), "cost_model": make_cost_model("wrench")}
    rngs = [np.random.default_rng(0)] * 3
    with pytest.raises(InvalidParameterError, match="batch"):
        grow_trees_together([simulator] * 3, task, roots, drives, rngs, start_times=times, batch=1, **options)
    with pytest.raises(InvalidParameterError, match="one entry per root"):
        grow_trees_together([simulator] * 3, task, roots, drives, rngs[:1], start_times=times, batch=4, **options)
