"""A control run's dataset: an episode with a physically impossible frame is left out, never labelled."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from energy_margin.control.episode_dataset import write_episodes_dataset
from energy_margin.control.episodes import run_control
from energy_margin.control.mppi import ControllerConfig
from energy_margin.data.dataset import Dataset, load_dataset
from energy_margin.data.validation import check_dataset, require_valid
from energy_margin.errors import EnergyMarginError


@pytest.fixture(scope="module")
def episodes(tmp_path_factory: pytest.TempPathFactory) -> Dataset:
    """Three real episodes of two cylinders under the hard disturbance."""
    out = tmp_path_factory.mktemp("control") / "run"
    _, dataset = run_control(
        "pushing", n_objects=2, episodes=3, policy="task", disturbance="hard", seed=3, out=out,
        task_overrides={"duration": 0.3}, controller=ControllerConfig(samples=3, horizon=2, period=0.05), n_frames=3,
        score_expansions=0,
    )  # fmt: skip
    return dataset


def _records(dataset: Dataset) -> list[dict[str, np.ndarray]]:
    """Each trajectory's arrays, as the episodes' records hold them."""
    return [{key: np.array(value[i]) for key, value in dataset.arrays.items()} for i in range(dataset.n_trajectories)]


def test_possible_episodes_are_all_kept(episodes: Dataset, tmp_path: Path) -> None:
    out = tmp_path / "run"
    out.mkdir()
    assert write_episodes_dataset(episodes.task, _records(episodes), out, extra={}) == []
    written = require_valid(out)
    assert written.n_trajectories == 3 and "dropped" not in written.metadata
    np.testing.assert_array_equal(written.arrays["object_pos"], episodes.arrays["object_pos"])


@pytest.mark.parametrize(
    ("where", "reason"),
    [
        # An object thrown 50 m away (a blown-up step): outside the task's frame box.
        ("outside", "frame 2: "),
        # An object pressed into the other one: deeper than the overlap limit.
        ("overlap", "frame 1: object 0 overlaps"),
    ],
)
def test_an_episode_with_an_impossible_frame_is_left_out_and_listed(
    episodes: Dataset, tmp_path: Path, where: str, reason: str
) -> None:
    records = _records(episodes)
    if where == "outside":
        records[1]["object_pos"][2, 0, 0] = 50.0
    else:
        records[1]["object_pos"][1, 0, :2] = records[1]["object_pos"][1, 1, :2]
    out = tmp_path / "run"
    out.mkdir()
    dropped = write_episodes_dataset(episodes.task, records, out, extra={"control": {"kept": True}})
    assert [entry["rollout"] for entry in dropped] == ["episode 1"]
    assert dropped[0]["reason"].startswith(reason)
    written = load_dataset(out)
    assert written.n_trajectories == 2 and written.metadata["dropped"] == dropped
    assert written.metadata["control"] == {"kept": True}
    # Episodes 0 and 2, unchanged; the dataset passes the checks analyze runs first.
    np.testing.assert_array_equal(written.arrays["object_pos"], episodes.arrays["object_pos"][[0, 2]])
    assert check_dataset(out) == []


def test_a_run_whose_every_episode_is_impossible_is_refused_and_writes_nothing(
    episodes: Dataset, tmp_path: Path
) -> None:
    records = _records(episodes)
    for record in records:
        record["object_pos"][0, 0, 0] = 50.0
    out = tmp_path / "run"
    out.mkdir()
    refused = r"^every episode has a physically impossible frame \(the first: episode 0:"
    with pytest.raises(EnergyMarginError, match=refused):
        write_episodes_dataset(episodes.task, records, out, extra={})
    assert list(out.iterdir()) == []
