"""The planar manipulator example in quick mode: the cup carries the cubes, then check, analyze, evaluate."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from example_runs import analyze_and_evaluate, generate_quick, write_example


@pytest.mark.slow
def test_planar_manipulator_example(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip(
        "dm_control", reason="the planar manipulator ships with dm_control (pip install 'energy-margin[examples]')"
    )
    out = tmp_path / "data"
    dataset = generate_quick(write_example("planar_manipulator", tmp_path), out)
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
    assert "positive rate" in analyze_and_evaluate(out, capsys)
