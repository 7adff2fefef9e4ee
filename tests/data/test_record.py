"""``record``: roll-outs of a plain MuJoCo loop become a dataset; bad recordings are one line each."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from energy_margin.cli import main
from energy_margin.data.dataset import load_dataset
from energy_margin.data.scores_file import load_scores
from energy_margin.tasks.scene_model import load_scene


def _log_rollout(scene: Path, path: Path, *, shift: float, steps: int = 80) -> dict[str, np.ndarray]:
    """Run the scene's model with its own loop (mocap pusher moved by hand) and save the log."""
    model = load_scene(scene).model
    data = mujoco.MjData(model)
    data.qpos[0:3] = [-0.06 + shift, 0.0, 0.03]
    data.qpos[7:10] = [0.06 + shift, 0.02, 0.03]
    log: dict[str, list[np.ndarray]] = {"time": [], "qpos": [], "qvel": []}
    for step in range(steps):
        t = step * model.opt.timestep
        data.mocap_pos[0] = [0.0, -0.15 + 0.3 * t, 0.03]
        log["time"].append(np.array(data.time))
        log["qpos"].append(data.qpos.copy())
        log["qvel"].append(data.qvel.copy())
        mujoco.mj_step(model, data)
    arrays = {key: np.stack(values) for key, values in log.items()}
    np.savez(path, **arrays)
    return arrays


def test_record_turns_logged_rollouts_into_a_dataset(tiny_scene: Path, tmp_path: Path, capsys) -> None:
    logs = [tmp_path / f"run{i}.npz" for i in range(2)]
    arrays = [_log_rollout(tiny_scene, log, shift=0.02 * i) for i, log in enumerate(logs)]
    out = tmp_path / "recorded"
    assert main(["record", "--scene", str(tiny_scene), *map(str, logs), "--frames", "4", "--out", str(out)]) == 0
    dataset = load_dataset(out)
    assert dataset.n_trajectories == 2 and dataset.n_frames == 4
    # Frames at the rows nearest to 0, 1/3, 2/3 and 1 of the roll-out's span: rows 0, 26, 53, 79.
    np.testing.assert_allclose(dataset.arrays["frame_time"][0], arrays[0]["time"][[0, 26, 53, 79]])
    np.testing.assert_allclose(dataset.arrays["object_pos"][1, 2, 1], arrays[1]["qpos"][53, 7:10])
    # The mocap coordinates of robot_q are the declared motion's at each frame time.
    np.testing.assert_allclose(dataset.arrays["robot_q"][0, :, 1], -0.15 + 0.3 * dataset.arrays["frame_time"][0])
    assert dataset.metadata["recorded_from"][0]["file"] == "run0.npz"
    assert dataset.arrays["captured"].any()
    assert main(["check", str(out)]) == 0
    assert main(["analyze", str(out), "--iterations", "20", "--workers", "1"]) == 0
    assert load_scores(out)["nodes"].min() > 1


@pytest.mark.parametrize(
    ("edit", "fragment"),
    [
        (lambda a: a.update(qpos=a["qpos"][:, :-1]), "qpos: has shape (80, 13), expected (80, 14)"),
        (lambda a: a.update(qvel=np.zeros((80, 11))), "qvel: has shape (80, 11), expected (80, 12)"),
        (lambda a: a["time"].__setitem__(5, a["time"][4]), "time: is not increasing (row 5"),
        (lambda a: a.pop("qvel"), "qvel: array is missing"),
        (lambda a: a.update(ctrl=np.zeros((80, 2))), "ctrl: has shape (80, 2), expected (80, 0)"),
        (lambda a: a["qpos"].__setitem__((3, 0), np.nan), "qpos: NaN or infinite value at row 3"),
    ],
)
def test_bad_recordings_are_one_line_naming_file_and_array(tiny_scene: Path, tmp_path: Path, capsys, edit, fragment):
    log = tmp_path / "run.npz"
    arrays = _log_rollout(tiny_scene, log, shift=0.0)
    edit(arrays)
    np.savez(log, **arrays)
    out = tmp_path / "recorded"
    assert main(["record", "--scene", str(tiny_scene), str(log), "--frames", "3", "--out", str(out)]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and f"{log}: {fragment}" in error, error
    assert not out.exists()


def test_record_reads_an_hdf5_file_with_a_group_per_rollout(tiny_scene: Path, tmp_path: Path, capsys) -> None:
    h5py = pytest.importorskip("h5py")
    first = _log_rollout(tiny_scene, tmp_path / "a.npz", shift=0.0)
    second = _log_rollout(tiny_scene, tmp_path / "b.npz", shift=0.02)
    path = tmp_path / "runs.h5"
    with h5py.File(path, "w") as handle:
        for name, arrays in (("run0", first), ("run1", second)):
            group = handle.create_group(name)
            for key, value in arrays.items():
                group[key] = value
    out = tmp_path / "from_h5"
    assert main(["record", "--scene", str(tiny_scene), str(path), "--frames", "3", "--out", str(out)]) == 0
    from_npz = tmp_path / "from_npz"
    npz = [str(tmp_path / "a.npz"), str(tmp_path / "b.npz")]
    assert main(["record", "--scene", str(tiny_scene), *npz, "--frames", "3", "--out", str(from_npz)]) == 0
    for key in ("object_pos", "robot_q", "captured", "in_success"):
        np.testing.assert_array_equal(load_dataset(out).arrays[key], load_dataset(from_npz).arrays[key])
    with h5py.File(path, "a") as handle:
        del handle["run1/qvel"]
        handle["run1/qvel"] = np.zeros((80, 3))
    assert main(["record", "--scene", str(tiny_scene), str(path), "--frames", "3", "--out", str(tmp_path / "bad")]) == 2
    assert f"{path}:/run1: qvel: has shape (80, 3), expected (80, 12)" in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()
