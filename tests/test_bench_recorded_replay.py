"""benchmarks/recorded_replay.py: a replay along the recorded path ends where the recording does."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bench_modules import load_benchmark
from energy_margin.data.record import record_dataset
from tiny_scene import ARM_OVER_PUCK, ARM_SCENE, write_arm_rollouts, write_tiny_scene


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("recorded_replay")


def test_the_arm_replayed_along_its_path_pushes_the_puck_where_it_was_recorded(bench, tmp_path: Path) -> None:
    scene = write_tiny_scene(tmp_path / "scene", scene=ARM_SCENE.replace("ROBOT", 'robot = "recorded"'),
                             model=ARM_OVER_PUCK)  # fmt: skip
    dataset = record_dataset(scene, write_arm_rollouts(tmp_path / "rollouts", count=2), n_frames=5,
                             out=tmp_path / "set")  # fmt: skip
    # The arm flung the puck about 0.9 m in the recording; the replay ends within 5 % of that.
    travel = np.linalg.norm(dataset.arrays["object_pos"][0, -1] - dataset.arrays["object_pos"][0, 0])
    assert travel > 0.5
    found = bench.replay(dataset, 0, 1e6)
    assert found["robot_deviation"] < 0.01
    assert found["object_distance_m"] < 0.05 * travel
    assert found["success_agrees"]
    # Too light an arm: its servo (kp 50, no command) pulls it off the path.
    assert bench.replay(dataset, 0, 100.0)["robot_deviation"] > 0.1
    rows = bench.armature_rows(dataset, 2, (1e6, 1e4))
    assert [row["armature"] for row in rows] == [1e6, 1e4]
    assert rows[0]["demonstrations"] == 2 and 0 <= rows[0]["success_agrees"] <= 2
    assert rows[0]["object_distance_median_m"] <= rows[0]["object_distance_max_m"]
