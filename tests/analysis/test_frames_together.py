"""A roll-out's frames grown together score as the frames grown one at a time."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from energy_margin.analysis.executors import LocalExecutor
from energy_margin.analysis.frame import AnalyzerConfig, FrameAnalyzer, analyze_frames
from energy_margin.data.dataset import load_dataset
from energy_margin.errors import InvalidParameterError
from energy_margin.sim import ENGINE_REGISTRY

TIMINGS = ("runtime_s", "physics_s")


def _comparable(rows: list[dict]) -> list[dict]:  # type: ignore[type-arg]
    return [{key: value for key, value in row.items() if key not in TIMINGS} for row in rows]


@pytest.fixture
def lockstep_mujoco(monkeypatch: pytest.MonkeyPatch) -> None:
    """The C MuJoCo engine, marked as one that grows a roll-out's trees together."""
    engine = dataclasses.replace(ENGINE_REGISTRY["mujoco"], grows_together=True)
    monkeypatch.setitem(ENGINE_REGISTRY, "mujoco", engine)


def test_rows_grown_together_equal_rows_one_at_a_time(tiny_dataset_source: Path, lockstep_mujoco: None) -> None:
    dataset = load_dataset(tiny_dataset_source)
    config = AnalyzerConfig(expansions=30, batch=4)
    indices = list(range(dataset.n_trajectories * dataset.n_frames))
    one_at_a_time = [FrameAnalyzer(dataset, config, seed=3)(index) for index in indices]
    analyzer = FrameAnalyzer(dataset, config, seed=3)
    assert analyzer._together
    together = list(analyzer.rows(indices))
    assert _comparable(together) == _comparable(one_at_a_time)
    # Through the executor too, on one worker and on a process pool (a chunk may span two roll-outs).
    assert _comparable(list(LocalExecutor(1).run(dataset, config, 3, indices))) == _comparable(one_at_a_time)
    pooled = LocalExecutor(2).run(dataset, config, 3, indices)
    pooled = sorted(pooled, key=lambda row: (row["trajectory"], row["frame"]))
    assert _comparable(pooled) == _comparable(one_at_a_time)


def test_continuations_of_frames_grown_together_equal_those_one_at_a_time(
    tiny_dataset_source: Path, lockstep_mujoco: None
) -> None:
    """Every frame's continuations run in one call, each with its roll-out's model and drive."""
    dataset = load_dataset(tiny_dataset_source)
    config = AnalyzerConfig(expansions=20, batch=4, continuation=6)
    indices = list(range(dataset.n_trajectories * dataset.n_frames))
    one_at_a_time = [FrameAnalyzer(dataset, config, seed=5)(index) for index in indices]
    analyzer = FrameAnalyzer(dataset, config, seed=5)
    assert analyzer._together
    assert _comparable(list(analyzer.rows(indices))) == _comparable(one_at_a_time)
    # The continuation decided the success scores: without it they differ.
    plain = list(FrameAnalyzer(dataset, dataclasses.replace(config, continuation=0), seed=5).rows(indices))
    assert [row["success_score"] for row in plain] != [row["success_score"] for row in one_at_a_time]


def test_analyze_frames_needs_batched_expansion(tiny_dataset_source: Path) -> None:
    dataset = load_dataset(tiny_dataset_source)
    frames = [dataset.frame(0, 0)]
    kwargs = {"frictions": [float(dataset.arrays["friction"][0])], "drives": [dataset.arrays["drive"][0]],
              "seeds": [0], "start_times": [0.0]}  # fmt: skip
    with pytest.raises(InvalidParameterError, match="batch > 1"):
        analyze_frames(dataset.task, frames, config=AnalyzerConfig(expansions=5), **kwargs)  # type: ignore[arg-type]


def test_a_device_engine_needs_batches_and_other_engines_take_no_device() -> None:
    with pytest.raises(InvalidParameterError, match="batch") as error:
        AnalyzerConfig(engine="mujoco-warp")
    assert error.value.parameter == "batch"
    with pytest.raises(InvalidParameterError, match="device") as error:
        AnalyzerConfig(device="cuda")
    assert error.value.parameter == "device"
    with pytest.raises(InvalidParameterError, match="device"):
        AnalyzerConfig(engine="mujoco-warp", batch=8, device="tpu")
    assert AnalyzerConfig(engine="mujoco-warp", batch=8, device="cpu").to_dict()["device"] == "cpu"


def test_roll_outs_a_propagator_cannot_mix_are_grown_one_roll_out_at_a_time(
    tiny_dataset_source: Path, lockstep_mujoco: None, monkeypatch: pytest.MonkeyPatch
) -> None:
    from energy_margin.sim.base import IncompatibleModelsError
    from energy_margin.sim.mujoco_rollout import RolloutPropagator

    calls: list[int] = []

    def refuse_mixtures(self, models) -> None:  # type: ignore[no-untyped-def]
        calls.append(len({id(model) for model in models}))
        if len({id(model) for model in models}) > 1:
            raise IncompatibleModelsError("models differ")

    monkeypatch.setattr(RolloutPropagator, "check_models", refuse_mixtures, raising=False)
    dataset = load_dataset(tiny_dataset_source)
    config = AnalyzerConfig(expansions=20, batch=4)
    indices = list(range(dataset.n_trajectories * dataset.n_frames))
    one_at_a_time = [FrameAnalyzer(dataset, config, seed=5)(index) for index in indices]
    together = list(FrameAnalyzer(dataset, config, seed=5).rows(indices))
    assert _comparable(together) == _comparable(one_at_a_time)
    assert calls[0] == 2  # both roll-outs were offered together first, and refused
