"""The Panda tray example in quick mode: Gymnasium-Robotics' Franka Panda carries four boxes on a tray."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from example_runs import analyze_and_evaluate, generate_quick, write_example

#: Height (m) of a box's origin resting on the tray at the start and at the destination.
START_Z, END_Z = 0.70, 0.78


@pytest.mark.slow
def test_panda_tray_example(tmp_path: Path, capsys) -> None:
    pytest.importorskip(
        "gymnasium_robotics",
        reason="the Panda tray example needs gymnasium-robotics (pip install 'energy-margin[examples]')",
    )
    out = tmp_path / "panda_data"
    dataset = generate_quick(write_example("panda_tray", tmp_path), out)
    assert dataset.n_objects == 4 and dataset.metadata["task"] == "scene"
    # The base joint (robot_q[0]) turned the arm a quarter turn, from +x to +y.
    robot_q = dataset.arrays["robot_q"]
    assert np.allclose(robot_q[:, 0, 0], 0.0, atol=0.01)
    assert np.allclose(robot_q[:, -1, 0], np.pi / 2, atol=0.05)
    pos = dataset.arrays["object_pos"]
    # The boxes start resting on the tray at x 0.62-0.82 m near y = 0 ...
    assert np.allclose(pos[:, 0, :, 2], START_Z, atol=0.003)
    assert (np.abs(pos[:, 0, :, 1]) < 0.1).all() and (pos[:, 0, :, 0] > 0.6).all()
    # ... and every box still on the tray at the end (its height) was carried round to the
    # destination near x = 0, y = 0.7 m; the rest fell to the floor. Both trajectories carry some.
    on_tray = np.abs(pos[:, -1, :, 2] - END_Z) < 0.01
    on_floor = pos[:, -1, :, 2] < 0.05
    assert (on_tray | on_floor).all() and on_tray.any(axis=1).all()
    carried = pos[:, -1][on_tray]
    assert (np.abs(carried[:, 0]) < 0.15).all() and (np.abs(carried[:, 1] - 0.7) < 0.16).all()
    assert "positive rate" in analyze_and_evaluate(out, capsys)
