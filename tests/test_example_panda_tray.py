"""The Panda tray example in quick mode: Gymnasium-Robotics' Franka Panda carries four boxes on a tray."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from energy_margin.cli import main
from energy_margin.data.dataset import load_dataset
from energy_margin.data.scores_file import load_scores

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "panda_tray"
#: Height (m) of a box's origin resting on the tray at the start and at the destination.
START_Z, END_Z = 0.70, 0.78


@pytest.mark.slow
def test_panda_tray_example(tmp_path: Path, capsys) -> None:
    pytest.importorskip(
        "gymnasium_robotics",
        reason="the Panda tray example needs gymnasium-robotics (pip install 'energy-margin[examples]')",
    )
    folder = tmp_path / "panda_tray"
    subprocess.run([sys.executable, str(EXAMPLE / "write_model.py"), "--out", str(folder)], check=True)
    shutil.copy(EXAMPLE / "panda_tray.toml", folder / "panda_tray.toml")
    out = tmp_path / "panda_data"
    arguments = ["--trajectories", "2", "--frames", "3", "--seed", "0", "--out", str(out)]
    assert main(["generate", "--scene", str(folder / "panda_tray.toml"), *arguments]) == 0
    dataset = load_dataset(out)
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
    assert main(["check", str(out)]) == 0
    assert main(["analyze", str(out), "--iterations", "15", "--workers", "1"]) == 0
    assert load_scores(out)["nodes"].min() > 1
    capsys.readouterr()
    assert main(["evaluate", str(out)]) == 0
    assert "positive rate" in capsys.readouterr().out
