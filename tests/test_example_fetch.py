"""The Fetch example in quick mode: Gymnasium-Robotics' Fetch pushes four blocks across its FetchPush table."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from example_runs import analyze_and_evaluate, generate_quick, write_example

#: The table top's height (m) and the x (m) where the goal area at its far side begins.
TABLE_TOP = 0.4
GOAL_X = 1.40


@pytest.mark.slow
def test_fetch_example(tmp_path: Path, capsys) -> None:
    pytest.importorskip(
        "gymnasium_robotics",
        reason="the Fetch example needs gymnasium-robotics (pip install 'energy-margin[examples]')",
    )
    out = tmp_path / "fetch_data"
    dataset = generate_quick(write_example("fetch", tmp_path), out)
    assert dataset.n_objects == 4 and dataset.metadata["task"] == "scene"
    robot_q = dataset.arrays["robot_q"]
    # The mocap body (after the 12 robot joints) moved the gripper 0.27 m along +x; the base is fixed.
    assert np.allclose(robot_q[:, -1, 12] - robot_q[:, 0, 12], 0.27, atol=1e-6)
    pos = dataset.arrays["object_pos"]
    # The paddle pushed the blocks forward (+x), along the table: none fell off or was lifted.
    assert (pos[:, -1, :, 0].mean(axis=1) > pos[:, 0, :, 0].mean(axis=1) + 0.1).all()
    assert np.allclose(pos[:, :, :, 2], TABLE_TOP + 0.025, atol=0.005)
    # At least two blocks of each trajectory reached the goal area at the far side.
    assert ((pos[:, -1, :, 0] > GOAL_X).sum(axis=1) >= 2).all()
    assert "positive rate" in analyze_and_evaluate(out, capsys)
