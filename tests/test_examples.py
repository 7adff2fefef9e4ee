"""The examples in quick mode: each scene file generated (or recorded), checked, analysed and evaluated."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from energy_margin.cli import main
from energy_margin.data.dataset import load_dataset
from example_runs import EXAMPLES, analyze_and_evaluate, generate_quick, write_example


@pytest.mark.slow
def test_pushing_scene_example(tmp_path: Path, capsys) -> None:
    out = tmp_path / "pushing"
    dataset = generate_quick(EXAMPLES / "pushing" / "pushing.toml", out)
    assert dataset.n_objects == 10 and dataset.metadata["task"] == "scene"
    # The pusher (robot_q[1] is its y) moves forward, as in the built-in task.
    assert (dataset.arrays["robot_q"][:, -1, 1] > dataset.arrays["robot_q"][:, 0, 1] + 0.3).all()
    assert "positive rate" in analyze_and_evaluate(out, capsys)


@pytest.mark.slow
def test_jaco_example(tmp_path: Path, capsys) -> None:
    pytest.importorskip(
        "dm_control", reason="the Jaco example needs dm_control (pip install 'energy-margin[examples]')"
    )
    out = tmp_path / "jaco_data"
    dataset = generate_quick(write_example("jaco", tmp_path), out)
    assert dataset.n_objects == 4
    # The paddle pushed the boxes forward (+y).
    pos = dataset.arrays["object_pos"]
    assert (pos[:, -1, :, 1].mean(axis=1) > pos[:, 0, :, 1].mean(axis=1) + 0.1).all()
    analyze_and_evaluate(out, capsys)


@pytest.mark.slow
def test_record_example(tmp_path: Path, capsys) -> None:
    logs = tmp_path / "logs"
    script = EXAMPLES / "record" / "simulate.py"
    subprocess.run([sys.executable, str(script), "--rollouts", "2", "--out", str(logs)], check=True)
    out = tmp_path / "recorded"
    rollouts = sorted(str(path) for path in logs.glob("run_*.npz"))
    scene = str(EXAMPLES / "record" / "tabletop.toml")
    assert main(["record", "--scene", scene, *rollouts, "--frames", "3", "--out", str(out)]) == 0
    assert load_dataset(out).n_trajectories == 2
    analyze_and_evaluate(out, capsys)


@pytest.mark.slow
def test_robomimic_example(tmp_path: Path, capsys) -> None:
    pytest.importorskip(
        "dm_control", reason="the Jaco model ships with dm_control (pip install 'energy-margin[examples]')"
    )
    h5py = pytest.importorskip("h5py", reason="robomimic files are HDF5 (pip install 'energy-margin[demos]')")
    jaco = write_example("jaco", tmp_path)
    demos = tmp_path / "demos.hdf5"
    script = EXAMPLES / "robomimic" / "write_demos.py"
    command = [sys.executable, str(script), "--demos", "2", "--scene", str(jaco), "--out", str(demos)]
    subprocess.run(command, check=True)
    with h5py.File(demos, "r") as handle:
        assert sorted(handle["data"]) == ["demo_0", "demo_1"]
        states = handle["data/demo_0/states"][()]
        assert states.shape[0] > 100 and np.all(np.diff(states[:, 0]) > 0)  # time, then qpos and qvel
        assert "<mujoco" in handle["data/demo_0"].attrs["model_file"]
    out = tmp_path / "demos_data"
    scene = EXAMPLES / "robomimic" / "jaco_demos.toml"
    arguments = ["record", "--format", "robomimic", str(demos), "--scene", str(scene), "--frames", "3"]
    assert main([*arguments, "--out", str(out)]) == 0
    dataset = load_dataset(out)
    assert dataset.n_objects == 4 and dataset.n_trajectories == 2
    # The boxes were pushed forward (+y) between the first and the last frame.
    pos = dataset.arrays["object_pos"]
    assert (pos[:, -1, :, 1].mean(axis=1) > pos[:, 0, :, 1].mean(axis=1) + 0.1).all()
    analyze_and_evaluate(out, capsys)
