"""benchmarks/bench_model_commands.py: both command paths on the same frames, the same scores."""

from __future__ import annotations

import argparse

import numpy as np
import pytest

from bench_modules import load_benchmark
from energy_margin.data.dataset import load_dataset
from energy_margin.data.generate import generate_dataset
from energy_margin.tasks import get_task
from energy_margin.tasks.scene_task import SceneTask


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("bench_model_commands")


def test_row_by_row_hides_the_batched_command_and_gives_it_back(bench, make_scene) -> None:
    task = get_task("scene", {"scene_file": str(make_scene())})
    drives, times = np.ones((2, 1)), np.array([0.0, 0.5])
    with bench._row_by_row():
        assert task.batched_model_command(drives, times) is None
    assert task.batched_model_command(drives, times) is not None
    assert SceneTask.batched_model_command.__name__ == "batched_model_command"


def test_both_sides_score_every_picked_frame_the_same(bench, make_scene, tmp_path) -> None:
    task = get_task("scene", {"scene_file": str(make_scene())})
    generate_dataset(task, n_objects=None, n_trajectories=2, n_frames=5, seed=3, out=tmp_path / "set")
    dataset = load_dataset(tmp_path / "set")
    args = argparse.Namespace(trajectories=1, frames=3, expansions=20, seed=0)
    assert bench._places(dataset, args) == [(0, [0, 2, 4])]
    row = bench.measure("tiny", dataset, args)
    assert (row["frames"], row["same_scores"]) == (3, 3)
    assert row["before_s"] > 0 and row["after_s"] > 0 and row["tree_s"] > 0
