"""Closed-loop episodes: the controller reaches an easy goal, runs are deterministic and resume."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from energy_margin.control.costs import CostWeights
from energy_margin.control.episode_draws import ControlSettings
from energy_margin.control.episode_scores import ControlResult, summarize
from energy_margin.control.episodes import CONTROL_FILE, run_control
from energy_margin.control.mppi import ControllerConfig
from energy_margin.data.dataset import Dataset, load_dataset
from energy_margin.errors import EnergyMarginError
from energy_margin.evaluation.statistics import wilson_interval
from energy_margin.runs.files import write_json

# One cylinder 0.1-0.15 m short of the wall band, the pusher 0.2-0.3 m behind it, and a script
# that pushes with no force: only a controller that pushes reaches the band in 1.5 s.
EASY = {
    "drive_factor": [0.0, 0.0],
    "spawn_y_top": 1.35,
    "spawn_depth_per_object": 0.005,
    "duration": 1.5,
    "drive_jitter": 0.0,
    "lateral_force": 0.0,
}
SMALL = ControllerConfig(samples=8, horizon=6, period=0.1)
# Shorter episodes for the bookkeeping tests.
SHORT = {**EASY, "duration": 0.3}
TINY = ControllerConfig(samples=3, horizon=2, period=0.05)


def test_controller_reaches_an_easy_goal_the_script_misses(tmp_path: Path) -> None:
    options = {"n_objects": 1, "episodes": 3, "disturbance": "none", "seed": 0, "score_expansions": 0}
    scripted, _ = run_control("pushing", policy="scripted", out=tmp_path / "s", task_overrides=EASY, **options)
    task, dataset = run_control(
        "pushing", policy="task", out=tmp_path / "t", task_overrides=EASY, controller=SMALL, **options
    )
    assert scripted.successes == 0
    assert task.successes == 3
    assert task.decisions == 3 * 15 and task.seconds_per_decision > 0
    assert dataset.arrays["in_success"][:, -1].all()


def _run(out: Path, **options: object) -> tuple[ControlResult, Dataset]:
    values: dict[str, object] = {
        "n_objects": 2,
        "episodes": 3,
        "policy": "task",
        "disturbance": "hard",
        "seed": 3,
        "task_overrides": SHORT,
        "controller": TINY,
        "n_frames": 3,
        "score_expansions": 2,
    }
    values.update(options)
    return run_control("pushing", out=out, **values)  # type: ignore[arg-type]


def test_same_seed_same_episodes_with_one_or_two_workers(tmp_path: Path) -> None:
    one, first = _run(tmp_path / "one")
    two, second = _run(tmp_path / "two", workers=2)
    for key in ("successes", "captured_fraction", "mean_capture_score", "decisions"):
        assert getattr(one, key) == getattr(two, key)
    for name, array in first.arrays.items():  # type: ignore[attr-defined]
        np.testing.assert_array_equal(array, second.arrays[name], err_msg=name)  # type: ignore[attr-defined]
    _, third = _run(tmp_path / "other", seed=4)
    assert not np.array_equal(first.arrays["object_pos"], third.arrays["object_pos"])  # type: ignore[attr-defined]


def test_an_interrupted_run_resumes_without_recomputing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    reference, reference_set = _run(tmp_path / "reference")

    def stop_after_first(index: int) -> None:
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        _run(tmp_path / "run", on_episode=stop_after_first)
    saved = sorted((tmp_path / "run" / "episodes").glob("*.npz"))
    assert len(saved) == 1
    assert not (tmp_path / "run" / "dataset.json").exists()
    from energy_margin.control import episodes

    calls: list[int] = []
    original = episodes.run_episode

    def counting(*args: object, **kwargs: object) -> dict:
        calls.append(1)
        return original(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(episodes, "run_episode", counting)
    resumed, resumed_set = _run(tmp_path / "run")
    assert len(calls) == 2
    timing = "seconds_per_decision"
    assert {k: v for k, v in resumed.to_dict().items() if k != timing} == {
        k: v for k, v in reference.to_dict().items() if k != timing
    }
    np.testing.assert_array_equal(resumed_set.arrays["object_pos"], reference_set.arrays["object_pos"])  # type: ignore[attr-defined]


def test_a_run_is_a_dataset_with_its_settings(tmp_path: Path) -> None:
    summary, _ = _run(tmp_path / "run", weights=CostWeights(margin=3.0))
    dataset = load_dataset(tmp_path / "run")
    assert dataset.n_trajectories == 3 and dataset.n_frames == 3
    control = dataset.metadata["control"]
    assert control["settings"]["policy"] == "task"
    assert control["settings"]["weights"]["margin"] == 3.0
    assert control["settings"]["disturbance"]["name"] == "hard"
    stored = json.loads((tmp_path / "run" / CONTROL_FILE).read_text())
    assert stored["summary"] == summary.to_dict()
    assert 0.0 <= summary.mean_capture_score <= 1.0
    low, high = summary.success_interval
    assert low <= summary.success_rate <= high


def test_a_run_grows_to_more_episodes_without_recomputing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    reference, reference_set = _run(tmp_path / "reference")
    _run(tmp_path / "run", episodes=2)
    from energy_margin.control import episodes

    calls: list[int] = []
    original = episodes.run_episode

    def counting(*args: object, **kwargs: object) -> dict:
        calls.append(1)
        return original(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(episodes, "run_episode", counting)
    grown, grown_set = _run(tmp_path / "run")
    assert len(calls) == 1
    np.testing.assert_array_equal(grown_set.arrays["object_pos"], reference_set.arrays["object_pos"])  # type: ignore[attr-defined]
    assert grown.successes == reference.successes and grown.episodes == 3


def test_other_settings_in_the_same_directory_are_refused(tmp_path: Path) -> None:
    _run(tmp_path / "run")
    with pytest.raises(EnergyMarginError, match="holds episodes of other settings"):
        _run(tmp_path / "run", policy="heuristic")
    summary, _ = _run(tmp_path / "run", policy="heuristic", overwrite=True)
    assert summary.policy == "heuristic"


def test_the_summary_is_typed_and_its_dictionary_is_the_json(tmp_path: Path) -> None:
    import warnings

    settings = ControlSettings(
        task="pushing", task_config={}, n_objects=2, episodes=2, policy="task", disturbance={"name": "mild"}, seed=0
    )
    infos = [
        {"success": True, "decisions": 4, "decision_seconds": 0.5, "captured_fraction": 1.0, "capture_scores": [0.5]},
        {"success": False, "decisions": 6, "decision_seconds": 1.5, "captured_fraction": 0.5},
    ]
    result = summarize(settings, infos)
    assert isinstance(result, ControlResult)
    assert result.successes == 1 and result.success_rate == 0.5 and result.seconds_per_decision == 0.2
    assert result.mean_capture_score == 0.5 and result.captured_fraction == 0.75
    # The JSON written (control.json's summary) is that of the dictionary earlier releases returned.
    low, high = wilson_interval(1, 2)
    earlier = {
        "task": "pushing",
        "n_objects": 2,
        "policy": "task",
        "disturbance": "mild",
        "episodes": 2,
        "successes": 1,
        "success_rate": 0.5,
        "success_interval": [low, high],
        "captured_fraction": 0.75,
        "mean_capture_score": 0.5,
        "decisions": 10,
        "seconds_per_decision": 0.2,
    }
    write_json(tmp_path / "typed.json", {"summary": result.to_dict()})
    write_json(tmp_path / "earlier.json", {"summary": earlier})
    assert (tmp_path / "typed.json").read_bytes() == (tmp_path / "earlier.json").read_bytes()
    assert ControlResult.from_dict(earlier) == result
    # Reading it as the dictionary of earlier releases still works, with a warning naming the attribute.
    with pytest.warns(DeprecationWarning, match=r"use \.success_rate"):
        assert result["success_rate"] == 0.5
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert "successes" in result and len(result) == len(earlier) and list(result) == list(earlier)


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"policy": "greedy"}, "unknown policy 'greedy'"),
        ({"policy": "learned"}, "needs `model`"),
        ({"episodes": 0}, "episodes must be a positive integer"),
        ({"n_frames": 1}, "frames must be an integer >= 2"),
        ({"disturbance": "storm"}, "unknown disturbance 'storm'"),
    ],
)
def test_bad_inputs_are_one_clear_error(tmp_path: Path, options: dict, message: str) -> None:
    with pytest.raises(EnergyMarginError, match=message):
        _run(tmp_path / "run", **options)
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize(
    ("successes", "trials", "expected"),
    [(5, 10, (0.2366, 0.7634)), (0, 10, (0.0, 0.2775)), (10, 10, (0.7225, 1.0)), (61, 100, (0.5120, 0.6998))],
)
def test_wilson_interval(successes: int, trials: int, expected: tuple[float, float]) -> None:
    assert wilson_interval(successes, trials) == pytest.approx(expected, abs=1e-4)


def test_a_scooping_episode_closes_and_lifts_on_the_script_timeline(tmp_path: Path) -> None:
    from energy_margin.tasks import get_task

    summary, dataset = run_control(
        "scooping",
        n_objects=1,
        episodes=1,
        policy="task",
        disturbance="none",
        seed=0,
        out=tmp_path / "scoop",
        controller=ControllerConfig(samples=2, horizon=1, period=0.1),
        n_frames=3,
        score_expansions=0,
    )
    task = get_task("scooping")
    assert summary.decisions == 23
    final = dataset.arrays["robot_q"][0, -1]  # type: ignore[attr-defined]
    # Fingers (coordinates 1 and 3) closed, base lifted most of lift_height above contact.
    assert final[1] == pytest.approx(task.closed_travel, abs=2e-3)
    assert final[0] > task.contact_height + 0.5 * task.config.lift_height
