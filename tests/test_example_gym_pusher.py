"""The Gymnasium Pusher arm example in quick mode: written, generated, checked, analysed and evaluated."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from example_runs import analyze_and_evaluate, generate_quick, write_example


@pytest.mark.slow
def test_gym_pusher_example(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip(
        "gymnasium", reason="the Pusher arm ships with gymnasium (pip install 'energy-margin[examples]')"
    )
    out = tmp_path / "gym_pusher_data"
    dataset = generate_quick(write_example("gym_pusher", tmp_path), out)
    assert dataset.n_objects == 4 and dataset.metadata["task"] == "scene"
    pos = dataset.arrays["object_pos"]
    # The tip swept along +y: at least two cylinders of every trajectory were carried 0.15 m or more that way,
    # and every cylinder still stands on the table (its centre within 1 cm of its start height).
    carried = pos[:, -1, :, 1] > pos[:, 0, :, 1] + 0.15
    assert (carried.sum(axis=1) >= 2).all()
    assert np.abs(pos[:, -1, :, 2] - pos[:, 0, :, 2]).max() < 0.01
    # The arm's shoulder pan (robot_q[0]) turned as the tip moved across the table.
    robot_q = dataset.arrays["robot_q"]
    assert (np.abs(robot_q[:, -1, 0] - robot_q[:, 0, 0]) > 0.5).all()
    assert "positive rate" in analyze_and_evaluate(out, capsys)
