from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.run import analyze
from energy_margin.data.dataset import load_dataset
from energy_margin.data.generate import generate_dataset
from energy_margin.errors import EnergyMarginError, InvalidDataError, InvalidParameterError
from energy_margin.learning.features import FrameFeatures, ObjectSetFeatures, SetInputs
from energy_margin.learning.margin_model import fit_margin_model, load_margin_model
from energy_margin.learning.set_network import (
    SetRegressor,
    _from_torch,
    _torch_network,
    fit_set_regressor,
)
from energy_margin.tasks import get_task
from energy_margin.world.state import FrameState

torch = pytest.importorskip("torch")


def random_inputs(rng: np.random.Generator, counts: list[int], channels: int = 5, width: int = 4) -> SetInputs:
    most = max(counts)
    objects = np.zeros((len(counts), most, channels))
    mask = np.zeros((len(counts), most), dtype=bool)
    for row, count in enumerate(counts):
        objects[row, :count] = rng.normal(size=(count, channels))
        mask[row, :count] = True
    return SetInputs(objects, mask, rng.normal(size=(len(counts), width)))


def random_regressor(seed: int, channels: int = 5, width: int = 4, hidden: int = 6) -> SetRegressor:
    torch.manual_seed(seed)
    network = _torch_network(torch, channels, width, hidden)
    rng = np.random.default_rng(seed)
    return _from_torch(
        network, rng.normal(size=channels), rng.uniform(0.5, 2, channels), rng.normal(size=width), np.ones(width)
    )


def test_numpy_forward_matches_pytorch() -> None:
    torch.manual_seed(3)
    network = _torch_network(torch, 5, 4, 6)
    inputs = random_inputs(np.random.default_rng(0), [3, 1, 5, 2])
    regressor = _from_torch(network, np.zeros(5), np.ones(5), np.zeros(4), np.ones(4))
    with torch.no_grad():
        logits = network(
            torch.as_tensor(inputs.objects, dtype=torch.float32),
            torch.as_tensor(inputs.mask),
            torch.as_tensor(inputs.frame, dtype=torch.float32),
        )
    np.testing.assert_allclose(regressor.predict(inputs), torch.sigmoid(logits).numpy(), atol=1e-5)


def test_output_ignores_object_order_and_padding() -> None:
    regressor = random_regressor(1)
    rng = np.random.default_rng(1)
    inputs = random_inputs(rng, [4])
    alone = regressor.predict(inputs)
    shuffled = SetInputs(inputs.objects[:, rng.permutation(4)], inputs.mask, inputs.frame)
    np.testing.assert_allclose(regressor.predict(shuffled), alone, atol=1e-12)
    # The same frame padded beside a frame of 7 objects.
    wide = SetInputs.concatenate([inputs, random_inputs(rng, [7])])
    np.testing.assert_allclose(regressor.predict(wide)[:1], alone, atol=1e-12)
    assert np.all((alone > 0) & (alone < 1))
    # It does look at every object: changing one changes the output.
    moved = inputs.objects.copy()
    moved[0, 2] += 3.0
    assert not np.allclose(regressor.predict(SetInputs(moved, inputs.mask, inputs.frame)), alone)


def test_take_and_concatenate_keep_frames() -> None:
    inputs = random_inputs(np.random.default_rng(2), [2, 6, 3])
    part = inputs.take(np.array([0, 2]))
    assert part.objects.shape == (2, 3, 5) and part.mask.sum() == 5
    joined = SetInputs.concatenate([part, inputs.take(slice(1, 2))])
    np.testing.assert_array_equal(joined.frame, inputs.frame[[0, 2, 1]])
    np.testing.assert_array_equal(joined.mask.sum(axis=1), [2, 3, 6])
    with pytest.raises(InvalidParameterError, match="at least one"):
        SetInputs.concatenate([])


def test_arrays_round_trip_and_validation() -> None:
    regressor = random_regressor(4)
    inputs = random_inputs(np.random.default_rng(4), [2, 3])
    again = SetRegressor.from_arrays(regressor.arrays())
    np.testing.assert_array_equal(again.predict(inputs), regressor.predict(inputs))
    arrays = regressor.arrays()
    del arrays["weight.key"]
    with pytest.raises(InvalidDataError, match=r"weight\.key"):
        SetRegressor.from_arrays(arrays)
    arrays = regressor.arrays()
    arrays["weight.head_0"] = arrays["weight.head_0"][:-1]
    with pytest.raises(InvalidDataError, match="head_0"):
        SetRegressor.from_arrays(arrays)


def test_object_set_features_are_the_per_object_channels_of_the_frame_statistics() -> None:
    task = get_task("pushing")
    rng = np.random.default_rng(5)
    dofs = task.robot_dofs()
    scene_frames = []
    for n in (2, 4):
        pos = np.column_stack([rng.uniform(-0.1, 0.1, (n, 2)), np.full(n, 0.02)])
        scene_frames.append(
            FrameState(
                pos, np.tile([1.0, 0, 0, 0], (n, 1)), rng.normal(0, 0.05, (n, 6)), np.zeros(dofs), np.zeros(dofs)
            )
        )
    inputs = ObjectSetFeatures(task)(scene_frames)
    statistics = FrameFeatures(task)(scene_frames)
    np.testing.assert_array_equal(inputs.frame, statistics)
    names = FrameFeatures(task).names
    for row, n in enumerate((2, 4)):
        channels = inputs.objects[row, :n]
        assert inputs.mask[row].sum() == n
        np.testing.assert_allclose(channels[:, 0].min(), statistics[row, names.index("dx_min")])
        np.testing.assert_allclose(channels[:, 3].max(), statistics[row, names.index("horizontal_distance_max")])
    assert ObjectSetFeatures(task).names[0] == "object.dx"
    assert ObjectSetFeatures(task).dimension == len(ObjectSetFeatures(task).names)


def test_fit_learns_a_set_function_and_stops_early() -> None:
    # Target: whether any object's first channel exceeds 1 (a max over the set).
    rng = np.random.default_rng(6)
    inputs = random_inputs(rng, list(rng.integers(1, 6, 600)), channels=3, width=2)
    first = np.where(inputs.mask, inputs.objects[:, :, 0], -np.inf).max(axis=1)
    targets = np.column_stack([(first > 1.0).astype(float), np.full(600, 0.3)])
    regressor, info = fit_set_regressor(inputs, targets, seed=0, hidden=16, epochs=120, patience=15)
    predicted = regressor.predict(inputs)
    accuracy = np.mean((predicted[:, 0] > 0.5) == (targets[:, 0] > 0.5))
    assert accuracy > 0.95
    assert abs(float(np.mean(predicted[:, 1])) - 0.3) < 0.03
    assert 1 <= info["best_epoch"] <= info["epochs"] <= 120
    with pytest.raises(InvalidParameterError, match="unknown set options: depth"):
        fit_set_regressor(inputs, targets, seed=0, depth=3)
    with pytest.raises(InvalidParameterError, match="targets must have shape"):
        fit_set_regressor(inputs, targets[:10], seed=0)


def test_the_same_data_and_seed_give_the_same_weights() -> None:
    rng = np.random.default_rng(8)
    inputs = random_inputs(rng, list(rng.integers(1, 5, 120)), channels=3, width=2)
    targets = np.column_stack([rng.random(120), rng.random(120)])
    groups = np.repeat(np.arange(30), 4)
    first, _ = fit_set_regressor(inputs, targets, seed=3, groups=groups, hidden=8, epochs=15, patience=5)
    again, _ = fit_set_regressor(inputs, targets, seed=3, groups=groups, hidden=8, epochs=15, patience=5)
    other, _ = fit_set_regressor(inputs, targets, seed=4, groups=groups, hidden=8, epochs=15, patience=5)
    assert np.array_equal(first.predict(inputs), again.predict(inputs))
    assert not np.array_equal(first.predict(inputs), other.predict(inputs))


def test_missing_pytorch_is_one_line(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "torch", None)
    inputs = random_inputs(np.random.default_rng(7), [2, 2])
    with pytest.raises(EnergyMarginError, match=r"pip install 'energy-margin\[learn\]'"):
        fit_set_regressor(inputs, np.zeros((2, 2)), seed=0)


@pytest.fixture(scope="module")
def two_sizes(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    root = tmp_path_factory.mktemp("sets")
    paths = []
    for n, seed in ((2, 1), (4, 2)):
        out = root / f"push{n}"
        generate_dataset("pushing", out=out, n_objects=n, n_trajectories=4, n_frames=3, seed=seed)
        analyze(out, AnalyzerConfig(expansions=8), seed=0, progress=False)
        paths.append(out)
    return paths


def test_one_set_model_scores_every_trained_count_and_refuses_others(two_sizes: list[Path], tmp_path: Path) -> None:
    datasets = [load_dataset(path) for path in two_sizes]
    model, report = fit_margin_model(datasets, seed=0, kind="set", hidden=8, epochs=4)
    assert model.n_objects_range == (2, 4) and report.n_trajectories["train"] + report.n_trajectories["held_out"] == 8
    model.save(tmp_path / "m.npz")
    loaded = load_margin_model(tmp_path / "m.npz", task_name="pushing")
    assert loaded.kind == "set" and loaded.n_objects_range == (2, 4)
    frames = [datasets[0].frame(0, 0), datasets[1].frame(0, 0)]
    np.testing.assert_array_equal(
        np.stack(loaded.predict(datasets[0].task, frames)), np.stack(model.predict(datasets[0].task, frames))
    )
    for dataset in datasets:
        loaded.check_dataset(dataset)
    three = tmp_path / "push3"
    generate_dataset("pushing", out=three, n_objects=3, n_trajectories=1, n_frames=2, seed=3)
    loaded.check_dataset(load_dataset(three))  # inside the range
    six = tmp_path / "push6"
    generate_dataset("pushing", out=six, n_objects=6, n_trajectories=1, n_frames=2, seed=3)
    with pytest.raises(EnergyMarginError, match="holds 6 objects and the model was fitted on 2 to 4"):
        loaded.check_dataset(load_dataset(six))
    scoop = tmp_path / "scoop"
    generate_dataset("scooping", out=scoop, n_objects=2, n_trajectories=1, n_frames=2, seed=0)
    with pytest.raises(EnergyMarginError, match="it is a dataset of task 'scooping'"):
        loaded.check_dataset(load_dataset(scoop))
