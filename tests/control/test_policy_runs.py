"""End-to-end ``control`` runs of the ``margin`` and ``learned`` policies.

Each run must complete, write a valid dataset whose summary agrees with its episodes, repeat
exactly with the same seed, and decide differently from ``task`` on the same seed because of its
score term (with the term's weight at 0 it decides exactly as ``task`` does).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.run import analyze
from energy_margin.cli import main
from energy_margin.control.costs import CostWeights
from energy_margin.control.episode_scores import ControlResult
from energy_margin.control.episodes import CONTROL_FILE, EPISODES_DIR, run_control
from energy_margin.control.mppi import ControllerConfig
from energy_margin.data.dataset import Dataset, load_dataset
from energy_margin.data.generate import generate_dataset
from energy_margin.data.validation import check_dataset
from energy_margin.evaluation.statistics import wilson_interval
from energy_margin.learning.margin_model import fit_margin_model
from energy_margin.runs.results import plain_result
from energy_margin.tasks import get_task

# Three objects under the hard disturbance for 0.5 s: 10 decisions of 4 samples per episode.
DURATION = 0.5
CONTROLLER = ControllerConfig(samples=4, horizon=2, period=0.05, margin_expansions=5, margin_samples=2)
OPTIONS: dict[str, Any] = {
    "n_objects": 3,
    "episodes": 2,
    "disturbance": "hard",
    "seed": 3,
    "task_overrides": {"duration": DURATION},
    "controller": CONTROLLER,
    "n_frames": 3,
    "score_expansions": 2,
}
DECISIONS_PER_EPISODE = round(DURATION / CONTROLLER.period)
# Arrays that depend on the decisions (the pusher's and the objects' motion, the labels).
DECIDED = ("robot_q", "robot_v", "object_pos", "object_vel")


def _episode_infos(out: Path, episodes: int) -> list[dict[str, Any]]:
    infos = []
    for index in range(episodes):
        with np.load(out / EPISODES_DIR / f"{index:05d}.npz", allow_pickle=False) as stored:
            infos.append(json.loads(str(stored["info"])))
    return infos


def _check_run(
    out: Path, result: ControlResult | dict[str, Any], dataset: Dataset, *, policy: str
) -> list[dict[str, Any]]:
    """The run's dataset is valid and its summary is what its episodes say; returns the episodes' info."""
    summary = plain_result(result)
    assert check_dataset(out) == []
    episodes = OPTIONS["episodes"]
    assert dataset.n_trajectories == episodes and dataset.n_frames == OPTIONS["n_frames"]
    infos = _episode_infos(out, episodes)
    arrays = dataset.arrays
    # The labels are the task's indicators of the recorded frames.
    task = get_task("pushing", OPTIONS["task_overrides"])
    for trajectory in range(episodes):
        for frame in range(dataset.n_frames):
            state = dataset.frame(trajectory, frame)
            assert bool(arrays["captured"][trajectory, frame]) == task.is_captured(state)
            assert bool(arrays["in_success"][trajectory, frame]) == task.is_successful(state)
    successes = int(arrays["in_success"][:, -1].sum())
    assert [info["success"] for info in infos] == arrays["in_success"][:, -1].tolist()
    assert summary["policy"] == policy and summary["episodes"] == episodes
    assert summary["successes"] == successes
    assert summary["success_rate"] == pytest.approx(successes / episodes)
    assert summary["success_interval"] == pytest.approx(list(wilson_interval(successes, episodes)))
    assert summary["captured_fraction"] == pytest.approx(float(arrays["captured"].mean()))
    expected_score = np.mean([np.mean(info["capture_scores"]) for info in infos])
    assert summary["mean_capture_score"] == pytest.approx(expected_score)
    assert all(len(info["capture_scores"]) == dataset.n_frames for info in infos)
    assert [info["decisions"] for info in infos] == [DECISIONS_PER_EPISODE] * episodes
    assert summary["decisions"] == episodes * DECISIONS_PER_EPISODE
    seconds = sum(info["decision_seconds"] for info in infos)
    assert summary["seconds_per_decision"] == pytest.approx(seconds / summary["decisions"])
    stored = json.loads((out / CONTROL_FILE).read_text())
    assert stored["summary"] == json.loads(json.dumps(summary))
    assert dataset.metadata["control"]["summary"] == stored["summary"]
    assert stored["settings"]["policy"] == policy
    return infos


def _without_timing(summary: ControlResult | dict[str, Any]) -> dict[str, Any]:
    return {key: value for key, value in plain_result(summary).items() if key != "seconds_per_decision"}


def _assert_same_runs(first: Dataset, second: Dataset) -> None:
    assert set(first.arrays) == set(second.arrays)
    for name, array in first.arrays.items():
        np.testing.assert_array_equal(array, second.arrays[name], err_msg=name)


def _differs(first: Dataset, second: Dataset) -> bool:
    return any(not np.array_equal(first.arrays[name], second.arrays[name]) for name in DECIDED)


@pytest.fixture(scope="module")
def task_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[ControlResult, Dataset]:
    """The ``task`` policy on the same episodes."""
    out = tmp_path_factory.mktemp("control") / "task"
    return run_control("pushing", policy="task", out=out, **OPTIONS)


def test_margin_policy_run(tmp_path: Path, task_run: tuple[ControlResult, Dataset]) -> None:
    summary, dataset = run_control("pushing", policy="margin", out=tmp_path / "margin", **OPTIONS)
    infos = _check_run(tmp_path / "margin", summary, dataset, policy="margin")
    # Every decision analysed its margin_samples lowest-cost samples.
    per_decision = min(CONTROLLER.margin_samples, CONTROLLER.samples)
    assert [info["analyses"] for info in infos] == [DECISIONS_PER_EPISODE * per_decision] * len(infos)
    again, again_set = run_control("pushing", policy="margin", out=tmp_path / "again", **OPTIONS)
    assert _without_timing(again) == _without_timing(summary)
    _assert_same_runs(dataset, again_set)
    # The score term decides: weighted 0 the margin policy does what task does, weighted 2 it does not.
    _, task_set = task_run
    _, unweighted = run_control(
        "pushing", policy="margin", out=tmp_path / "unweighted", weights=CostWeights(margin=0.0), **OPTIONS
    )
    for name in DECIDED:
        np.testing.assert_array_equal(unweighted.arrays[name], task_set.arrays[name], err_msg=name)
    assert _differs(dataset, task_set)


@pytest.fixture(scope="module")
def model_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small MLP margin fitted on 6 analysed pushing trajectories of 3 objects x 3 frames."""
    root = tmp_path_factory.mktemp("learned")
    generate_dataset("pushing", out=root / "train", n_objects=3, n_trajectories=6, n_frames=3, seed=2)
    analyze(root / "train", AnalyzerConfig(expansions=8), seed=0, progress=False)
    model, _ = fit_margin_model([load_dataset(root / "train")], seed=0, kind="mlp", hidden=(8,), max_iter=40)
    path = root / "push3.npz"
    model.save(path)
    return path


def _control_cli(out: Path, policy: str, *extra: str) -> None:
    args = [
        "control",
        "--objects",
        str(OPTIONS["n_objects"]),
        "--episodes",
        str(OPTIONS["episodes"]),
        "--disturbance",
        OPTIONS["disturbance"],
        "--seed",
        str(OPTIONS["seed"]),
        "--set",
        f"duration={DURATION}",
        "--samples",
        str(CONTROLLER.samples),
        "--horizon",
        str(CONTROLLER.horizon),
        "--period",
        str(CONTROLLER.period),
        "--margin-expansions",
        str(CONTROLLER.margin_expansions),
        "--margin-samples",
        str(CONTROLLER.margin_samples),
        "--frames",
        str(OPTIONS["n_frames"]),
        "--expansions",
        str(OPTIONS["score_expansions"]),
        "--policy",
        policy,
        "--out",
        str(out),
        "--json",
        *extra,
    ]
    assert main(args) == 0


@pytest.mark.filterwarnings("ignore::sklearn.exceptions.ConvergenceWarning")
def test_learned_policy_run(
    tmp_path: Path,
    model_file: Path,
    task_run: tuple[ControlResult, Dataset],
    capsys: pytest.CaptureFixture[str],
) -> None:
    out = tmp_path / "learned"
    _control_cli(out, "learned", "--model", str(model_file))
    summary = json.loads(capsys.readouterr().out)
    dataset = load_dataset(out)
    infos = _check_run(out, summary, dataset, policy="learned")
    assert all(info["analyses"] == 0 for info in infos)  # the model scores the samples: no tree
    model_info = json.loads((out / CONTROL_FILE).read_text())["settings"]["model"]
    assert model_info == {"path": str(model_file), "sha256": hashlib.sha256(model_file.read_bytes()).hexdigest()}
    _control_cli(tmp_path / "again", "learned", "--model", str(model_file))
    assert _without_timing(json.loads(capsys.readouterr().out)) == _without_timing(summary)
    _assert_same_runs(dataset, load_dataset(tmp_path / "again"))
    # The learned term decides: weighted 0 the policy does what task does, weighted 2 it does not.
    _, task_set = task_run
    _control_cli(tmp_path / "unweighted", "learned", "--model", str(model_file), "--margin-weight", "0")
    capsys.readouterr()
    unweighted = load_dataset(tmp_path / "unweighted")
    for name in DECIDED:
        np.testing.assert_array_equal(unweighted.arrays[name], task_set.arrays[name], err_msg=name)
    assert _differs(dataset, task_set)
