"""``record``: roll-outs of a plain MuJoCo loop become a dataset; bad recordings are one line each."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from energy_margin.cli import main
from energy_margin.data.dataset import load_dataset
from energy_margin.data.scores_file import load_scores
from energy_margin.runs.versions import engine_versions
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
    assert dataset.metadata["versions"] == engine_versions("mujoco")
    assert dataset.arrays["captured"].any()
    assert main(["check", str(out)]) == 0
    assert main(["analyze", str(out), "--expansions", "20", "--workers", "1"]) == 0
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


def _log_turned_pusher(scene: Path, path: Path, *, steps: int = 40, mocap: bool = True) -> dict[str, np.ndarray]:
    """A user's loop that holds the pusher still at its start, turned half a revolution about z.

    The scene file declares a pusher that moves along +y unturned, so the declared motion's
    capture region (0.02-0.22 m in front of the pusher) holds both boxes while the recorded
    pusher's region lies behind it, away from them.
    """
    model = load_scene(scene).model
    data = mujoco.MjData(model)
    data.qpos[0:3] = [-0.06, 0.05, 0.03]
    data.qpos[7:10] = [0.06, 0.05, 0.03]
    names = ("time", "qpos", "qvel", "mocap_pos", "mocap_quat")
    log: dict[str, list[np.ndarray]] = {name: [] for name in names}
    for _ in range(steps):
        data.mocap_pos[0] = [0.0, -0.15, 0.03]
        data.mocap_quat[0] = [0.0, 0.0, 0.0, 1.0]
        log["time"].append(np.array(data.time))
        log["qpos"].append(data.qpos.copy())
        log["qvel"].append(data.qvel.copy())
        log["mocap_pos"].append(data.mocap_pos.copy())
        log["mocap_quat"].append(data.mocap_quat.copy())
        mujoco.mj_step(model, data)
    arrays = {key: np.stack(values) for key, values in log.items()}
    np.savez(path, **(arrays if mocap else {key: arrays[key] for key in ("time", "qpos", "qvel")}))
    return arrays


def test_recorded_mocap_arrays_override_the_declared_motion(tiny_scene: Path, tmp_path: Path) -> None:
    from energy_margin.analysis.frame import AnalyzerConfig
    from energy_margin.analysis.run import analyze
    from energy_margin.data.record import record_dataset
    from energy_margin.data.validation import check_dataset

    # The capture region taken at the analysed (recorded) frame: a region that follows the pusher would
    # be taken where the declared motion moves it in each tree state (a mocap pose is commanded).
    tiny_scene.write_text(tiny_scene.read_text().replace("[capture]\n", "[capture]\nfollow = false\n"))
    arrays = _log_turned_pusher(tiny_scene, tmp_path / "turned.npz")
    _log_turned_pusher(tiny_scene, tmp_path / "declared.npz", mocap=False)
    turned = record_dataset(tiny_scene, [tmp_path / "turned.npz"], n_frames=4, out=tmp_path / "with_mocap")
    declared = record_dataset(tiny_scene, [tmp_path / "declared.npz"], n_frames=4, out=tmp_path / "without")
    assert check_dataset(tmp_path / "with_mocap") == []
    rows = [0, 13, 26, 39]  # nearest to 0, 1/3, 2/3 and 1 of the roll-out's span
    np.testing.assert_allclose(turned.arrays["frame_time"][0], arrays["time"][rows])
    # robot_q: the mocap position (3) then quaternion (4), as recorded, not as declared.
    robot_q = turned.arrays["robot_q"][0]
    np.testing.assert_allclose(robot_q[:, :3], arrays["mocap_pos"][rows, 0])
    np.testing.assert_allclose(robot_q[:, 3:], arrays["mocap_quat"][rows, 0])
    times = declared.arrays["frame_time"][0]
    np.testing.assert_allclose(declared.arrays["robot_q"][0, :, 1], -0.15 + 0.3 * times)
    np.testing.assert_allclose(declared.arrays["robot_q"][0, :, 3:], np.tile([1.0, 0, 0, 0], (4, 1)), atol=1e-12)
    np.testing.assert_array_equal(turned.arrays["object_pos"], declared.arrays["object_pos"])
    # The labels are those of the recorded pusher: its capture region is behind it.
    assert declared.arrays["captured"].all()
    assert not turned.arrays["captured"].any()
    # The analysis starts from the recorded pusher and scores against its capture region.
    simulator = turned.task.make_simulator(
        turned.n_objects, float(turned.arrays["friction"][0]), turned.arrays["drive"][0]
    )
    for frame, row in enumerate(rows):
        simulator.reset(turned.frame(0, frame))
        np.testing.assert_allclose(simulator.data.mocap_pos[0], arrays["mocap_pos"][row, 0])  # type: ignore[attr-defined]
        np.testing.assert_allclose(simulator.data.mocap_quat[0], arrays["mocap_quat"][row, 0])  # type: ignore[attr-defined]
    config = AnalyzerConfig(expansions=15)
    analyze(tmp_path / "with_mocap", config, seed=0, progress=False)
    analyze(tmp_path / "without", config, seed=0, progress=False)
    turned_capture = load_scores(tmp_path / "with_mocap")["capture_score"]
    declared_capture = load_scores(tmp_path / "without")["capture_score"]
    assert turned_capture.max() <= 0.01
    assert declared_capture.min() >= 0.5


def _fly_away(arrays: dict[str, np.ndarray], row: int) -> None:
    """Put object 0 19 km/s and 11,500 km away from ``row`` on, as a blown-up simulation leaves it."""
    arrays["qpos"][row:, 0:3] = [1.15e7, 0.0, 0.03]
    arrays["qvel"][row:, 0:3] = [1.9e4, 0.0, 0.0]


def test_a_physically_impossible_roll_out_is_refused_in_one_line(tiny_scene: Path, tmp_path: Path, capsys) -> None:
    log = tmp_path / "run.npz"
    arrays = _log_rollout(tiny_scene, log, shift=0.0)
    _fly_away(arrays, 60)
    np.savez(log, **arrays)
    out = tmp_path / "recorded"
    assert main(["record", "--scene", str(tiny_scene), str(log), "--frames", "4", "--out", str(out)]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1, error
    assert f"{log}: qpos: row 79 (frame 3): object 0 at (1.15e+07, 0, 0.03) m lies outside the bounds" in error
    assert "--drop-unphysical" in error
    assert not out.exists()


def test_drop_unphysical_leaves_the_roll_out_out_and_lists_it(tiny_scene: Path, tmp_path: Path, capsys) -> None:
    logs = [tmp_path / f"run{i}.npz" for i in range(3)]
    for index, log in enumerate(logs):
        arrays = _log_rollout(tiny_scene, log, shift=0.02 * index)
        if index == 1:
            _fly_away(arrays, 30)
            arrays["qpos"][30:, 0:3] = [0.0, 0.0, 0.03]  # in place, but 19 km/s
            np.savez(log, **arrays)
    out = tmp_path / "recorded"
    command = ["record", "--scene", str(tiny_scene), *map(str, logs), "--frames", "4", "--out", str(out)]
    assert main([*command, "--drop-unphysical"]) == 0
    printed = capsys.readouterr().out
    assert "left out 1 roll-out(s) with a physically impossible frame" in printed
    dataset = load_dataset(out)
    assert dataset.n_trajectories == 2
    (dropped,) = dataset.metadata["dropped"]
    assert dropped["rollout"] == str(logs[1])
    assert "object 0 moves at 1.9e+04 m/s, faster than 10 m/s" in dropped["reason"]
    assert main(["check", str(out)]) == 0


def test_a_roll_out_during_which_mujoco_warned_is_refused(tiny_scene: Path, tmp_path: Path, capsys) -> None:
    from energy_margin.sim.mujoco_audit import PHYSICS_WARNINGS, WARNINGS_ARRAY

    log = tmp_path / "run.npz"
    arrays = _log_rollout(tiny_scene, log, shift=0.0)
    counts = np.zeros((80, len(PHYSICS_WARNINGS)))
    counts[50:, list(PHYSICS_WARNINGS).index("mjWARN_BADQVEL")] = 1
    np.savez(log, **arrays, **{WARNINGS_ARRAY: counts})
    out = tmp_path / "recorded"
    assert main(["record", "--scene", str(tiny_scene), str(log), "--frames", "4", "--out", str(out)]) == 2
    error = capsys.readouterr().err
    assert f"{log}: {WARNINGS_ARRAY}: row 50: MuJoCo warned mjWARN_BADQVEL during the roll-out" in error
    assert not out.exists()
