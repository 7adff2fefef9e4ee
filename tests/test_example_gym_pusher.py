"""The Gymnasium Pusher arm example in quick mode: written, generated, checked, analysed and evaluated."""

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

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "gym_pusher"
QUICK = ["--trajectories", "2", "--frames", "3", "--seed", "0"]


@pytest.mark.slow
def test_gym_pusher_example(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip(
        "gymnasium", reason="the Pusher arm ships with gymnasium (pip install 'energy-margin[examples]')"
    )
    folder = tmp_path / "gym_pusher"
    subprocess.run([sys.executable, str(EXAMPLE / "write_model.py"), "--out", str(folder)], check=True)
    shutil.copy(EXAMPLE / "gym_pusher.toml", folder / "gym_pusher.toml")
    out = tmp_path / "gym_pusher_data"
    assert main(["generate", "--scene", str(folder / "gym_pusher.toml"), *QUICK, "--out", str(out)]) == 0
    dataset = load_dataset(out)
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
    assert main(["check", str(out)]) == 0
    assert main(["analyze", str(out), "--iterations", "15", "--workers", "1"]) == 0
    assert load_scores(out)["nodes"].min() > 1
    capsys.readouterr()
    assert main(["evaluate", str(out)]) == 0
    assert "positive rate" in capsys.readouterr().out
