from __future__ import annotations

import json
import os
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from energy_margin import __version__
from energy_margin.data.dataset import FRAMES_FILE, METADATA_FILE, Dataset, load_dataset
from energy_margin.data.generate import generate_dataset, record_trajectory
from energy_margin.errors import EnergyMarginError, InvalidParameterError
from energy_margin.tasks import PushingTask

SHAPES = {
    "object_pos": (2, 3, 2, 3),
    "object_quat": (2, 3, 2, 4),
    "object_vel": (2, 3, 2, 6),
    "robot_q": (2, 3, 4),
    "robot_v": (2, 3, 4),
    "frame_time": (2, 3),
    "friction": (2,),
    "drive": (2, 2),
    "captured": (2, 3),
    "in_success": (2, 3),
}


def _tree(root: Path) -> dict[str, bytes]:
    """Every file under ``root`` (hidden ones included) with its content."""
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


# ---------------------------------------------------------------- generate and load


def test_generate_then_load_round_trip(tmp_path: Path) -> None:
    out = tmp_path / "data"
    generated = generate_dataset("pushing", n_objects=2, n_trajectories=2, n_frames=3, seed=4, out=out)
    assert sorted(p.name for p in out.iterdir()) == [METADATA_FILE, FRAMES_FILE]
    assert [p.name for p in tmp_path.iterdir()] == ["data"]  # no staging directory left behind
    loaded = load_dataset(out)
    assert loaded.path == out
    assert set(loaded.arrays) == set(SHAPES)
    for name, shape in SHAPES.items():
        assert loaded.arrays[name].shape == shape, name
        assert loaded.arrays[name].dtype == (np.bool_ if name in ("captured", "in_success") else np.float64), name
        assert np.array_equal(loaded.arrays[name], generated.arrays[name]), name
    meta = loaded.metadata
    assert meta == json.loads(json.dumps(generated.metadata))
    assert meta["format"] == "energy-margin-dataset"
    assert meta["schema_version"] == 1
    assert meta["task"] == "pushing"
    assert meta["engine"] == "mujoco"
    assert (meta["seed"], meta["n_trajectories"], meta["n_frames"], meta["n_objects"]) == (4, 2, 3, 2)
    assert (meta["n_robot_dofs"], meta["n_drive"]) == (4, 2)
    assert meta["package_version"] == __version__
    assert meta["task_config"] == json.loads(json.dumps(PushingTask().config.to_dict()))
    assert (loaded.n_trajectories, loaded.n_frames, loaded.n_objects) == (2, 3, 2)
    assert isinstance(loaded.task, PushingTask)


def test_frames_and_labels_are_consistent(tiny_dataset: Path) -> None:
    dataset = load_dataset(tiny_dataset)
    task = dataset.task
    # Frames at steps 0, 120, 240 of a 2 s roll-out at 1/120 s.
    np.testing.assert_allclose(dataset.arrays["frame_time"], [[0.0, 1.0, 2.0]] * 2)
    for t in range(2):
        first = dataset.frame(t, 0)
        first.validate(n_objects=2, n_robot_dofs=4)
        friction = dataset.arrays["friction"][t]
        assert 0.1 <= friction <= 0.3
        for k in range(3):
            frame = dataset.frame(t, k)
            assert dataset.arrays["captured"][t, k] == task.is_captured(frame)
            assert dataset.arrays["in_success"][t, k] == task.is_successful(frame)
    # The pusher drives the objects forward (+y) over the roll-out.
    assert np.all(dataset.arrays["object_pos"][:, -1, :, 1] > dataset.arrays["object_pos"][:, 0, :, 1])


def test_first_frame_is_the_sampled_initial_state() -> None:
    task = PushingTask()
    record = record_trajectory(task, 2, 4, np.random.default_rng(9))
    trajectory = task.sample_trajectory(np.random.default_rng(9), 2)
    np.testing.assert_allclose(record["object_pos"][0], trajectory.initial.object_pos, atol=1e-12)
    np.testing.assert_allclose(record["robot_q"][0], trajectory.initial.robot_q, atol=1e-12)
    assert record["friction"] == trajectory.friction
    np.testing.assert_array_equal(record["drive"], trajectory.drive)
    assert record["object_pos"].shape == (4, 2, 3)


def test_generation_is_deterministic(tmp_path: Path) -> None:
    for name, seed in (("a", 1), ("b", 1), ("c", 2)):
        generate_dataset("pushing", n_objects=2, n_trajectories=2, n_frames=3, seed=seed, out=tmp_path / name)
    first, again, other = (load_dataset(tmp_path / name) for name in "abc")
    for name in SHAPES:
        assert np.array_equal(first.arrays[name], again.arrays[name]), name
    assert first.metadata == again.metadata
    assert (tmp_path / "a" / METADATA_FILE).read_bytes() == (tmp_path / "b" / METADATA_FILE).read_bytes()
    assert not np.array_equal(first.arrays["object_pos"], other.arrays["object_pos"])


def test_trajectory_i_does_not_depend_on_the_number_of_trajectories(tmp_path: Path) -> None:
    one = generate_dataset("pushing", n_objects=2, n_trajectories=1, n_frames=3, seed=8, out=tmp_path / "one")
    three = generate_dataset("pushing", n_objects=2, n_trajectories=3, n_frames=3, seed=8, out=tmp_path / "three")
    for name in SHAPES:
        assert np.array_equal(one.arrays[name][0], three.arrays[name][0]), name


def test_task_overrides_reach_the_data(tmp_path: Path) -> None:
    dataset = generate_dataset(
        "pushing",
        n_objects=1,
        n_trajectories=2,
        n_frames=2,
        seed=0,
        out=tmp_path / "d",
        task_config={"friction_range": [0.25, 0.26], "duration": 1.0},
    )
    assert np.all((dataset.arrays["friction"] >= 0.25) & (dataset.arrays["friction"] <= 0.26))
    np.testing.assert_allclose(dataset.arrays["frame_time"][:, -1], 1.0)
    assert load_dataset(tmp_path / "d").task.config.friction_range == (0.25, 0.26)


def test_progress_is_called_once_per_trajectory(tmp_path: Path) -> None:
    calls: list[int] = []
    generate_dataset(
        "pushing", n_objects=1, n_trajectories=3, n_frames=2, seed=0, out=tmp_path / "p", progress=calls.append
    )
    assert calls == [1, 1, 1]


# ---------------------------------------------------------------- labels


def _labels_dataset(captured: list[list[bool]], in_success: list[list[bool]] | None = None) -> Dataset:
    arrays = {"captured": np.array(captured, dtype=bool)}
    if in_success is not None:
        arrays["in_success"] = np.array(in_success, dtype=bool)
    return Dataset(path=None, metadata={}, arrays=arrays)


def test_capture_labels_window_truncates_at_the_end() -> None:
    t, f = True, False
    dataset = _labels_dataset([[t, t, f, t, t], [t, t, t, t, t], [f, t, t, t, f]])
    np.testing.assert_array_equal(dataset.capture_labels(0), dataset.arrays["captured"])
    np.testing.assert_array_equal(dataset.capture_labels(), dataset.arrays["captured"])
    np.testing.assert_array_equal(dataset.capture_labels(1), [[t, f, f, t, t], [t] * 5, [f, t, t, f, f]])
    np.testing.assert_array_equal(dataset.capture_labels(2), [[f, f, f, t, t], [t] * 5, [f, t, f, f, f]])
    # A window longer than the trajectory: every frame needs all later frames captured; the last
    # frame only needs itself.
    np.testing.assert_array_equal(dataset.capture_labels(10), [[f, f, f, t, t], [t] * 5, [f, f, f, f, f]])
    assert not np.shares_memory(dataset.capture_labels(0), dataset.arrays["captured"])
    with pytest.raises(InvalidParameterError, match="window must be a non-negative integer, got -1"):
        dataset.capture_labels(-1)


def test_success_labels_use_the_last_frame() -> None:
    t, f = True, False
    dataset = _labels_dataset([[t, t]] * 3, in_success=[[t, f], [f, t], [t, t]])
    labels = dataset.success_labels()
    np.testing.assert_array_equal(labels, [f, t, t])
    labels[:] = False
    np.testing.assert_array_equal(dataset.success_labels(), [f, t, t])  # a copy was returned


def test_generated_labels_follow_the_rules(tiny_dataset: Path) -> None:
    dataset = load_dataset(tiny_dataset)
    np.testing.assert_array_equal(dataset.success_labels(), dataset.arrays["in_success"][:, -1])
    captured = dataset.arrays["captured"]
    expected = captured.copy()
    expected[:, 0] = captured[:, 0] & captured[:, 1]
    expected[:, 1] = captured[:, 1] & captured[:, 2]
    np.testing.assert_array_equal(dataset.capture_labels(1), expected)


# ---------------------------------------------------------------- bad generation input


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"n_objects": 0}, "n_objects must be a positive integer, got 0"),
        ({"n_trajectories": 0}, "n_trajectories must be a positive integer, got 0"),
        ({"n_frames": 0}, "n_frames must be a positive integer, got 0"),
        ({"seed": -1}, "seed must be a non-negative integer, got -1"),
        ({"n_objects": True}, "n_objects must be a positive integer, got True"),
        ({"n_frames": 2.5}, "n_frames must be a positive integer, got 2.5"),
        ({"task_name": "stacking"}, "unknown task 'stacking'"),
        ({"engine": "bullet"}, "unknown engine 'bullet'"),
        ({"task_config": {"bogus": 1}}, "unknown pushing configuration keys: bogus"),
        (
            {"n_objects": 2, "task_config": {"min_separation": 5.0}},
            "cannot generate pushing trajectories: cannot place 2 objects",
        ),
    ],
)
def test_bad_generation_input_writes_nothing(tmp_path: Path, kwargs: dict[str, object], message: str) -> None:
    values: dict[str, object] = {"task_name": "pushing", "n_objects": 1, "n_trajectories": 1, "n_frames": 2, "seed": 0}
    values.update(kwargs)
    task_name = values.pop("task_name")
    with pytest.raises(EnergyMarginError, match=message):
        generate_dataset(task_name, out=tmp_path / "out", **values)
    assert list(tmp_path.iterdir()) == []


def test_existing_directory_is_not_replaced_without_overwrite(tmp_path: Path) -> None:
    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.txt").write_text("precious")
    with pytest.raises(EnergyMarginError, match="already exists; pass `overwrite=True`"):
        generate_dataset("pushing", n_objects=1, n_trajectories=1, n_frames=2, seed=0, out=out)
    assert _tree(tmp_path) == {"out/keep.txt": b"precious"}
    generate_dataset("pushing", n_objects=1, n_trajectories=1, n_frames=2, seed=0, out=out, overwrite=True)
    assert sorted(_tree(tmp_path)) == ["out/dataset.json", "out/frames.npz"]


def test_existing_file_is_not_replaced_without_overwrite(tmp_path: Path) -> None:
    out = tmp_path / "out"
    out.write_text("a file")
    with pytest.raises(EnergyMarginError, match="already exists"):
        generate_dataset("pushing", n_objects=1, n_trajectories=1, n_frames=2, seed=0, out=out)
    assert out.read_text() == "a file"


def test_existing_empty_directory_is_used(tmp_path: Path) -> None:
    out = tmp_path / "out"
    out.mkdir()
    generate_dataset("pushing", n_objects=1, n_trajectories=1, n_frames=2, seed=0, out=out)
    load_dataset(out)


def test_other_dataset_is_not_replaced_without_overwrite(tiny_dataset: Path) -> None:
    before = _tree(tiny_dataset)
    with pytest.raises(EnergyMarginError, match="already exists"):
        generate_dataset("pushing", n_objects=2, n_trajectories=2, n_frames=3, seed=99, out=tiny_dataset)
    assert _tree(tiny_dataset) == before
    generate_dataset("pushing", n_objects=2, n_trajectories=2, n_frames=3, seed=99, out=tiny_dataset, overwrite=True)
    assert load_dataset(tiny_dataset).metadata["seed"] == 99


def test_same_settings_reuse_the_existing_dataset(tiny_dataset: Path) -> None:
    (tiny_dataset / "scores.csv").write_text("kept")
    stamp = os.stat(tiny_dataset / FRAMES_FILE).st_mtime_ns
    reused = generate_dataset("pushing", n_objects=2, n_trajectories=2, n_frames=3, seed=0, out=tiny_dataset)
    assert os.stat(tiny_dataset / FRAMES_FILE).st_mtime_ns == stamp
    assert (tiny_dataset / "scores.csv").read_text() == "kept"
    assert reused.metadata["seed"] == 0
    assert reused.path == tiny_dataset


# ---------------------------------------------------------------- bad datasets on load


def _expect_load_error(directory: Path, message: str) -> None:
    with pytest.raises(EnergyMarginError, match=message):
        load_dataset(directory)


def test_missing_directory(tmp_path: Path) -> None:
    _expect_load_error(tmp_path / "nope", "does not exist or is not a directory")


def test_missing_metadata(tiny_dataset: Path) -> None:
    (tiny_dataset / METADATA_FILE).unlink()
    _expect_load_error(tiny_dataset, "dataset.json does not exist")


def test_invalid_metadata_json(tiny_dataset: Path) -> None:
    (tiny_dataset / METADATA_FILE).write_text("{not json")
    _expect_load_error(tiny_dataset, "is not valid JSON")


def _edit_metadata(directory: Path, **changes: object) -> None:
    path = directory / METADATA_FILE
    meta = json.loads(path.read_text())
    for key, value in changes.items():
        if value is None:
            meta.pop(key)
        else:
            meta[key] = value
    path.write_text(json.dumps(meta))


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"schema_version": 2}, "schema_version: 2 is not supported"),
        ({"schema_version": None}, "schema_version: None is not supported"),
        ({"format": "something-else"}, "is not an energy-margin dataset"),
        ({"n_objects": None}, "n_objects: is missing"),
        ({"n_frames": 0}, "n_frames: must be an integer"),
        ({"n_trajectories": "2"}, "n_trajectories: must be an integer"),
        ({"n_objects": 3}, "frames.npz: object_pos: has shape"),
        ({"task": "stacking"}, "unknown task 'stacking'"),
        ({"task_config": {"bogus": 1}}, "config names unknown pushing configuration keys: bogus"),
    ],
)
def test_bad_metadata(tiny_dataset: Path, changes: dict[str, object], message: str) -> None:
    _edit_metadata(tiny_dataset, **changes)
    _expect_load_error(tiny_dataset, message)


def test_metadata_that_is_not_an_object(tiny_dataset: Path) -> None:
    (tiny_dataset / METADATA_FILE).write_text("[1, 2]")
    _expect_load_error(tiny_dataset, "is not an energy-margin dataset")


def test_missing_frames(tiny_dataset: Path) -> None:
    (tiny_dataset / FRAMES_FILE).unlink()
    _expect_load_error(tiny_dataset, "frames.npz is missing")


@pytest.mark.parametrize(
    "content",
    [b"", b"garbage, not an archive", b"PK\x03\x04 truncated zip"],
    ids=["empty", "garbage", "truncated-zip"],
)
def test_garbage_frames(tiny_dataset: Path, content: bytes) -> None:
    (tiny_dataset / FRAMES_FILE).write_bytes(content)
    _expect_load_error(tiny_dataset, r"frames.npz: .*corrupt")


def test_truncated_frames(tiny_dataset: Path) -> None:
    path = tiny_dataset / FRAMES_FILE
    path.write_bytes(path.read_bytes()[:300])
    _expect_load_error(tiny_dataset, r"frames.npz: .*corrupt")


def test_object_arrays_are_refused(tiny_dataset: Path, rewrite_frames: Callable[..., None]) -> None:
    rewrite_frames(tiny_dataset, drive=np.array([{"a": 1}, {"b": 2}], dtype=object))
    _expect_load_error(tiny_dataset, "frames.npz: drive: holds Python objects")


@pytest.mark.parametrize(
    ("name", "index", "where"),
    [
        ("object_pos", (1, 2, 0, 1), "trajectory 1, frame 2"),
        ("object_vel", (0, 1, 1, 4), "trajectory 0, frame 1"),
        ("robot_q", (1, 0, 3), "trajectory 1, frame 0"),
        ("frame_time", (0, 2), "trajectory 0, frame 2"),
        ("friction", (1,), "trajectory 1"),
        ("drive", (0, 1), "trajectory 0"),
    ],
)
@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_values_name_the_array(
    tiny_dataset: Path, rewrite_frames: Callable[..., None], name: str, index: tuple[int, ...], where: str, bad: float
) -> None:
    with np.load(tiny_dataset / FRAMES_FILE) as archive:
        array = archive[name].copy()
    array[index] = bad
    rewrite_frames(tiny_dataset, **{name: array})
    with pytest.raises(EnergyMarginError, match=f"frames.npz: {name} \\[{where}.*\\]: NaN or infinite value") as info:
        load_dataset(tiny_dataset)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize(
    ("replacement", "message"),
    [
        ({"captured": np.ones((2, 3), dtype=np.int64)}, "frames.npz: captured: labels must be booleans"),
        ({"object_pos": np.zeros((2, 3, 2, 3), dtype=np.int64)}, "frames.npz: object_pos: must hold floats"),
        ({"robot_v": np.zeros((2, 3, 3))}, r"frames.npz: robot_v: has shape \(2, 3, 3\), expected \(2, 3, 4\)"),
        ({"friction": np.array([0.2, -0.1])}, "negative coefficient"),
        (
            {"object_quat": np.full((2, 3, 2, 4), 0.6)},
            r"object_quat \[trajectory 0, frame 0, object 0\]: not a unit quaternion",
        ),
    ],
)
def test_invalid_arrays(
    tiny_dataset: Path, rewrite_frames: Callable[..., None], replacement: dict[str, np.ndarray], message: str
) -> None:
    rewrite_frames(tiny_dataset, **replacement)
    _expect_load_error(tiny_dataset, message)


def test_missing_array(tiny_dataset: Path) -> None:
    path = tiny_dataset / FRAMES_FILE
    with np.load(path) as archive:
        arrays = {name: archive[name] for name in archive.files if name != "in_success"}
    np.savez(path, **arrays)
    _expect_load_error(tiny_dataset, "frames.npz: in_success: array is missing")


def test_archive_without_arrays(tiny_dataset: Path) -> None:
    with zipfile.ZipFile(tiny_dataset / FRAMES_FILE, "w") as archive:
        archive.writestr("notes.txt", "hello")
    _expect_load_error(tiny_dataset, "frames.npz: object_pos: array is missing")


# Known defects: these corrupt archives escape as non-EnergyMarginError exceptions.


def test_plain_npy_file_instead_of_an_archive(tiny_dataset: Path) -> None:
    with (tiny_dataset / FRAMES_FILE).open("wb") as stream:
        np.save(stream, np.zeros(3))
    _expect_load_error(tiny_dataset, "frames.npz")


def test_damaged_compressed_data(tiny_dataset: Path) -> None:
    path = tiny_dataset / FRAMES_FILE
    data = bytearray(path.read_bytes())
    for i in range(200, 260):
        data[i] ^= 0xFF
    path.write_bytes(bytes(data))
    _expect_load_error(tiny_dataset, r"frames.npz: .*corrupt")


def test_archive_member_that_is_not_an_array(tiny_dataset: Path) -> None:
    with zipfile.ZipFile(tiny_dataset / FRAMES_FILE, "w") as archive:
        archive.writestr("object_pos.npy", b"definitely not an npy file")
    _expect_load_error(tiny_dataset, "object_pos")


def test_loading_a_dataset_resolves_its_task_once(tiny_dataset: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import energy_margin.data.dataset as dataset_module

    calls: list[str] = []
    real = dataset_module.get_recorded_task

    def counting(name: str, config: dict | None) -> object:
        calls.append(name)
        return real(name, config)

    monkeypatch.setattr(dataset_module, "get_recorded_task", counting)
    dataset = load_dataset(tiny_dataset)
    task = dataset.task
    assert calls == [dataset.metadata["task"]]
    assert task is dataset.task
    assert task.config == real(dataset.metadata["task"], dataset.metadata["task_config"]).config
