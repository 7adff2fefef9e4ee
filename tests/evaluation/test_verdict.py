"""The verdict of evaluate: the margin against the best baseline with a paired bootstrap interval."""

from __future__ import annotations

import json

import numpy as np
import pytest

from energy_margin.cli import main
from energy_margin.data.dataset import Dataset
from energy_margin.data.generate import generate_dataset
from energy_margin.evaluation.baselines import distance_scores
from energy_margin.evaluation.metrics import evaluate
from energy_margin.evaluation.verdict import verdicts, word
from score_files import write_scores

QUESTIONS = ("capture_ap", "capture_ap_window2", "success_ap", "success_ap_first_half")


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Dataset:
    """Twelve short pushing trajectories of 3 objects (labels of both classes)."""
    out = tmp_path_factory.mktemp("verdict") / "d"
    return generate_dataset("pushing", n_objects=3, n_trajectories=12, n_frames=6, seed=3, out=out)


def _current(dataset: Dataset) -> tuple[np.ndarray, np.ndarray]:
    return dataset.arrays["captured"].astype(float), dataset.arrays["in_success"].astype(float)


def _verdicts(dataset: Dataset, margin: tuple[np.ndarray, np.ndarray], seed: int = 0) -> dict:  # type: ignore[type-arg]
    baselines = {"current_state": _current(dataset), "chance": (np.zeros((12, 6)), np.zeros((12, 6)))}
    distance = distance_scores(dataset)
    assert distance is not None
    baselines["distance"] = distance
    return verdicts(
        dataset, margin, baselines, capture_window=0, success_frames=3, weights="linear", resamples=200, seed=seed
    )


def test_the_words() -> None:
    assert word(0.1, 0.02, 0.2) == "ahead"
    assert word(-0.1, -0.2, -0.01) == "behind"
    assert word(0.05, -0.01, 0.1) == "level"
    assert word(0.0, 0.0, 0.0) == "level"
    assert word(None, None, None) == "n/a"
    assert word(0.1, None, None) == "n/a"


def test_a_margin_equal_to_the_best_baseline_is_level_with_a_zero_interval(dataset: Dataset) -> None:
    found = _verdicts(dataset, _current(dataset))
    # The current-state indicator answers capture at k-hat = 0 perfectly: it is the best baseline there.
    verdict = found["capture_ap"]
    assert verdict.baseline == "current_state"
    assert (verdict.difference, verdict.low, verdict.high, verdict.word) == (0.0, 0.0, 0.0, "level")
    assert 0 < verdict.resamples <= 200
    assert "chance" not in {v.baseline for v in found.values()}


def test_a_reversed_margin_is_behind_and_an_oracle_is_not(dataset: Dataset) -> None:
    captured, in_success = _current(dataset)
    reversed_found = _verdicts(dataset, (1.0 - captured, 1.0 - in_success))
    assert reversed_found["capture_ap"].word == "behind"
    assert reversed_found["capture_ap"].high is not None and reversed_found["capture_ap"].high < 0
    labels2 = dataset.capture_labels(2).astype(float)
    success = np.repeat(dataset.success_labels().astype(float)[:, None], 6, axis=1)
    oracle = _verdicts(dataset, (labels2, success))
    assert oracle["capture_ap_window2"].difference is not None and oracle["capture_ap_window2"].difference >= 0
    assert oracle["capture_ap_window2"].word in {"ahead", "level"}
    assert oracle["success_ap_first_half"].word in {"ahead", "level"}


def test_the_same_seed_gives_the_same_verdict(dataset: Dataset) -> None:
    rng = np.random.default_rng(1)
    margin = (rng.random((12, 6)), rng.random((12, 6)))
    first, again = _verdicts(dataset, margin, seed=4), _verdicts(dataset, margin, seed=4)
    assert first == again


def test_evaluate_reports_the_verdict_in_the_table_and_in_json(
    dataset: Dataset, capsys: pytest.CaptureFixture[str]
) -> None:
    rng = np.random.default_rng(2)
    write_scores(dataset.path, rng.random((12, 6)), rng.random((12, 6)))
    result = evaluate(dataset.path, resamples=100, seed=1)
    assert set(result.verdict) == set(QUESTIONS)
    assert {v["word"] for v in result.verdict.values()} <= {"ahead", "level", "behind", "n/a"}
    assert result.verdict_resamples == 100
    assert "verdict" not in evaluate(dataset.path, resamples=0)
    assert main(["evaluate", str(dataset.path), "--resamples", "100", "--seed", "1", "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed["verdict"] == json.loads(json.dumps(result.verdict))
    assert main(["evaluate", str(dataset.path), "--resamples", "100"]) == 0
    table = capsys.readouterr().out
    assert "margin - best baseline [95 %]" in table
    assert "verdict: paired bootstrap over trajectories (100 resamples, seed 0)" in table
    with pytest.raises(SystemExit):
        main(["evaluate", str(dataset.path), "--resamples", "-1"])


def test_the_table_says_when_an_interval_rests_on_fewer_resamples() -> None:
    from energy_margin.evaluation.metrics import verdict_cell

    verdict = {"difference": 0.1, "low": 0.02, "high": 0.2, "word": "ahead", "baseline": "distance"}
    assert verdict_cell({**verdict, "resamples": 1000}, 1000) == "+0.100 [+0.020, +0.200] ahead (distance)"
    assert verdict_cell({**verdict, "resamples": 640}, 1000).endswith(
        "(distance; interval from 640 of 1000 resamples, 360 had labels of one class: no AP)"
    )
