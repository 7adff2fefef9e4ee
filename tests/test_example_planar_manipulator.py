"""The planar manipulator example in quick mode: the cup carries the cubes, then check, analyze, evaluate."""

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

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "planar_manipulator"


@pytest.mark.slow
def test_planar_manipulator_example(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip(
        "dm_control", reason="the planar manipulator ships with dm_control (pip install 'energy-margin[examples]')"
    )
    folder = tmp_path / "planar_manipulator"
    subprocess.run([sys.executable, str(EXAMPLE / "write_model.py"), "--out", str(folder)], check=True)
    shutil.copy(EXAMPLE / "planar_manipulator.toml", folder / "planar_manipulator.toml")
    out = tmp_path / "data"
    scene = str(folder / "planar_manipulator.toml")
    assert (
        main(["generate", "--scene", scene, "--trajectories", "2", "--frames", "3", "--seed", "0", "--out", str(out)])
        == 0
    )
    dataset = load_dataset(out)
    assert dataset.n_objects == 3
    # The cubes start in the cup on the floor at x = -0.2 m, ride up with it (half way through the
    # motion they are over 10 cm up) and are set down with it at x = 0.25 m, staying in the arm's
    # plane (y = 0) all the way.
    pos = dataset.arrays["object_pos"]
    assert np.all(np.abs(pos[:, 0, :, 0] + 0.2) < 0.05) and np.all(pos[:, 0, :, 2] < 0.03)
    assert np.all(pos[:, 1, :, 2] > 0.1)
    assert np.all(np.abs(pos[:, -1, :, 0] - 0.25) < 0.06) and np.all(pos[:, -1, :, 2] < 0.05)
    assert np.all(np.abs(pos[..., 1]) < 0.02)
    assert dataset.arrays["captured"].all() and dataset.arrays["in_success"][:, -1].all()
    assert main(["check", str(out)]) == 0
    assert main(["analyze", str(out), "--iterations", "15", "--workers", "1"]) == 0
    assert load_scores(out)["nodes"].min() > 1
    capsys.readouterr()
    assert main(["evaluate", str(out)]) == 0
    assert "positive rate" in capsys.readouterr().out
