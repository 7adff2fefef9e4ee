from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from sklearn.metrics import average_precision_score

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.run import analyze
from energy_margin.data.dataset import load_dataset
from energy_margin.data.scores_file import SCORES_FILE, load_scores
from energy_margin.errors import EnergyMarginError
from energy_margin.evaluation.metrics import average_precision, evaluate, format_table, score_grid
from score_files import write_scores

REQUIRED = {
    "capture_ap",
    "success_ap",
    "capture_positive_rate",
    "success_positive_rate",
    "n_frames",
    "n_trajectories",
    "runtime_per_frame_s",
    "baselines",
}
QUESTIONS = {"capture_ap", "capture_ap_window2", "success_ap", "success_ap_first_half"}

# Hand-made labels for a 2 x 3 dataset: mixed capture labels and mixed final success.
CAPTURED = np.array([[True, False, True], [True, True, False]])
IN_SUCCESS = np.array([[False, True, True], [False, False, False]])


@pytest.fixture
def labelled(tiny_dataset: Path, rewrite_frames: Callable[..., None]) -> Path:
    """The tiny dataset with the hand-made labels above."""
    rewrite_frames(tiny_dataset, captured=CAPTURED, in_success=IN_SUCCESS)
    return tiny_dataset


# ---------------------------------------------------------------- average precision


def test_average_precision_single_class_is_none() -> None:
    assert average_precision(np.ones(5, dtype=bool), np.linspace(0, 1, 5)) is None
    assert average_precision(np.zeros(5, dtype=bool), np.linspace(0, 1, 5)) is None
    assert average_precision(np.zeros((2, 2), dtype=bool), np.zeros((2, 2))) is None


def test_average_precision_matches_sklearn() -> None:
    rng = np.random.default_rng(0)
    for _ in range(10):
        labels = rng.random(40) < 0.3
        labels[:2] = [True, False]
        scores = rng.random(40) + 0.3 * labels
        assert average_precision(labels, scores) == pytest.approx(average_precision_score(labels, scores), abs=1e-15)
    # Perfect ranking, flattened 2-D input.
    labels = np.array([[True, False], [False, True]])
    assert average_precision(labels, labels.astype(float)) == 1.0
    # Constant scores: AP is the positive rate.
    assert average_precision(np.array([1, 0, 0, 0]), np.zeros(4)) == pytest.approx(0.25)


# ---------------------------------------------------------------- score_grid


def _scores(rows: list[tuple[int, int, float]]) -> dict[str, np.ndarray]:
    return {
        "trajectory": np.array([r[0] for r in rows]),
        "frame": np.array([r[1] for r in rows]),
        "capture_score": np.array([r[2] for r in rows]),
    }


def test_score_grid_arranges_rows(tiny_dataset: Path) -> None:
    dataset = load_dataset(tiny_dataset)
    rows = [(1, 2, 0.6), (0, 0, 0.1), (0, 1, 0.2), (0, 2, 0.3), (1, 0, 0.4), (1, 1, 0.5)]
    np.testing.assert_array_equal(
        score_grid(dataset, _scores(rows), "capture_score"), [[0.1, 0.2, 0.3], [0.4, 0.5, 0.6]]
    )


@pytest.mark.parametrize(
    ("rows", "message"),
    [
        (
            [(0, 0, 0.1), (0, 1, 0.2), (0, 2, 0.3), (1, 0, 0.4), (1, 1, 0.5), (1, 1, 0.6)],
            "2 rows for trajectory 1, frame 1",
        ),
        ([(0, 0, 0.1), (0, 1, 0.2), (0, 2, 0.3), (1, 0, 0.4), (1, 1, 0.5)], "0 rows for trajectory 1, frame 2"),
        (
            [(0, 0, 0.1), (0, 1, 0.2), (0, 2, 0.3), (1, 0, 0.4), (1, 1, 0.5), (2, 0, 0.6)],
            "trajectory 2, frame 0 is outside",
        ),
        ([(0, 0, 0.1), (0, 1, 0.2), (0, 3, 0.3), (1, 0, 0.4), (1, 1, 0.5), (1, 2, 0.6)], "frame 3 is outside"),
        (
            [(0, 0, 0.1), (0, 1, 0.2), (0, 2, np.nan), (1, 0, 0.4), (1, 1, 0.5), (1, 2, 0.6)],
            "NaN or infinite capture_score",
        ),
        ([], "0 rows for trajectory 0, frame 0"),
    ],
    ids=["duplicate", "missing", "bad-trajectory", "bad-frame", "nan", "empty"],
)
def test_score_grid_rejects_incomplete_tables(
    tiny_dataset: Path, rows: list[tuple[int, int, float]], message: str
) -> None:
    dataset = load_dataset(tiny_dataset)
    with pytest.raises(EnergyMarginError, match=message):
        score_grid(dataset, _scores(rows), "capture_score")


def test_evaluate_refuses_a_duplicated_row(labelled: Path) -> None:
    write_scores(labelled, CAPTURED.astype(float), IN_SUCCESS.astype(float))
    text = (labelled / SCORES_FILE).read_text().splitlines(keepends=True)
    (labelled / SCORES_FILE).write_text("".join([*text[:-1], text[2]]))  # frame (0, 1) twice, (1, 2) missing
    with pytest.raises(EnergyMarginError, match=r"duplicates line 3 \(trajectory 0, frame 1\)"):
        evaluate(labelled)


# ---------------------------------------------------------------- evaluate


def test_evaluate_an_analyzed_dataset(tiny_dataset: Path) -> None:
    analyze(tiny_dataset, AnalyzerConfig(expansions=30), seed=0, progress=False)
    result = evaluate(tiny_dataset)
    assert set(result) >= REQUIRED
    assert set(result) >= QUESTIONS
    assert set(result.baselines) == {"current_state", "chance", "distance"}
    for name in ("current_state", "chance", "distance"):
        assert set(result.baselines[name]) == QUESTIONS
    dataset = load_dataset(tiny_dataset)
    assert result.n_frames == 6
    assert result.n_trajectories == 2
    assert result.n_objects == 2
    assert result.task == "pushing"
    assert result.capture_positive_rate == pytest.approx(dataset.capture_labels(0).mean())
    assert result.success_positive_rate == pytest.approx(dataset.success_labels().mean())
    assert result.runtime_per_frame_s == pytest.approx(load_scores(tiny_dataset)["runtime_s"].mean())
    assert result.runtime_per_frame_s > 0
    for key in QUESTIONS:
        value = getattr(result, key)
        assert value is None or 0.0 <= value <= 1.0
    table = format_table(result)
    assert "capture AP, k-hat=0" in table
    assert "current_state" in table


def test_scores_equal_to_the_labels_give_perfect_ap(labelled: Path) -> None:
    dataset = load_dataset(labelled)
    # Perfect capture scores at k-hat = 0; success scores equal to in_success make every
    # trajectory score its final label.
    write_scores(labelled, CAPTURED.astype(float), IN_SUCCESS.astype(float), runtime=0.5)
    result = evaluate(labelled)
    assert result.capture_ap == 1.0
    assert result.success_ap == 1.0
    assert result.capture_positive_rate == pytest.approx(4 / 6)
    assert result.success_positive_rate == pytest.approx(0.5)
    assert result.capture_positive_rate_window2 == pytest.approx(dataset.capture_labels(2).mean())
    assert result.runtime_per_frame_s == 0.5
    assert result.physics_per_frame_s == 0.25
    # The current-state baseline is the capture label itself at k-hat = 0.
    assert result.baselines["current_state"]["capture_ap"] == 1.0
    # A constant score's AP is the positive rate.
    assert result.baselines["chance"]["capture_ap"] == pytest.approx(4 / 6)
    assert result.baselines["chance"]["success_ap"] == pytest.approx(0.5)
    # The first half of the frames (frame 0) holds no success yet: constant scores.
    assert result.success_ap_first_half == pytest.approx(0.5)


def test_each_capture_key_holds_one_window_and_the_table_one_line_per_k_hat(
    labelled: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from energy_margin.cli import main

    dataset = load_dataset(labelled)
    write_scores(labelled, dataset.capture_labels(2).astype(float), IN_SUCCESS.astype(float))
    # k-hat 0: capture_ap at 0 and capture_ap_window2 at 2, one line each.
    result = evaluate(labelled, resamples=20)
    assert result.capture_ap < 1.0 and result.capture_ap_window2 == 1.0
    assert result.capture_positive_rate_window2 == pytest.approx(dataset.capture_labels(2).mean())
    table = format_table(result)
    assert table.count("capture AP, k-hat=0") == 1 and table.count("capture AP, k-hat=2") == 1
    # k-hat 2: capture_ap is that question, and no second key (nor line) repeats it.
    result = evaluate(labelled, capture_window=2, resamples=20)
    assert result.capture_window == 2 and result.capture_ap == 1.0
    assert "capture_ap_window2" not in result and "capture_positive_rate_window2" not in result
    assert result.capture_positive_rate == pytest.approx(dataset.capture_labels(2).mean())
    for values in (*result.baselines.values(), result.verdict):
        assert set(values) == QUESTIONS - {"capture_ap_window2"}
    assert main(["evaluate", str(labelled), "--capture-window", "2", "--resamples", "20"]) == 0
    out = capsys.readouterr().out
    assert out.count("capture AP, k-hat=") == 1 and "capture AP, k-hat=2" in out


def test_inverted_scores_give_poor_ap(labelled: Path) -> None:
    write_scores(labelled, 1.0 - CAPTURED, 1.0 - IN_SUCCESS)
    result = evaluate(labelled)
    assert result.capture_ap < 0.7
    assert result.success_ap == pytest.approx(0.5)


def test_capture_window_and_success_frames(labelled: Path) -> None:
    dataset = load_dataset(labelled)
    window1 = dataset.capture_labels(1)
    write_scores(labelled, window1.astype(float), IN_SUCCESS.astype(float))
    assert evaluate(labelled, capture_window=1).capture_ap == 1.0
    assert evaluate(labelled, capture_window=1).capture_positive_rate == pytest.approx(window1.mean())
    assert evaluate(labelled).capture_ap < 1.0
    # Success scores that only look right early: with k-bar = 3 (all frames) the ranking is right,
    # with k-bar = 1 (last frame only) it is wrong.
    early = np.array([[1.0, 1.0, 0.0], [0.0, 0.0, 0.5]])
    write_scores(labelled, window1.astype(float), early)
    assert evaluate(labelled, success_frames=3, weights="uniform").success_ap == 1.0
    assert evaluate(labelled, success_frames=1).success_ap == pytest.approx(0.5)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"capture_window": -1}, "capture_window must be a non-negative integer, got -1"),
        ({"capture_window": 1.5}, "capture_window must be a non-negative integer, got 1.5"),
        ({"success_frames": 0}, "success_frames must be a positive integer, got 0"),
        ({"weights": "exponential"}, "weights must be one of linear, uniform, got 'exponential'"),
    ],
)
def test_evaluate_rejects_bad_options(labelled: Path, kwargs: dict[str, object], message: str) -> None:
    write_scores(labelled, CAPTURED.astype(float), IN_SUCCESS.astype(float))
    with pytest.raises(EnergyMarginError, match=message):
        evaluate(labelled, **kwargs)


def test_evaluate_needs_scores(tiny_dataset: Path) -> None:
    with pytest.raises(EnergyMarginError, match=r"has no scores\.csv; run `energy-margin analyze` first"):
        evaluate(tiny_dataset)
    assert sorted(p.name for p in tiny_dataset.iterdir()) == ["dataset.json", "frames.npz"]


def test_evaluate_missing_dataset(tmp_path: Path) -> None:
    with pytest.raises(EnergyMarginError, match="does not exist"):
        evaluate(tmp_path / "nope")


def test_the_evaluation_is_typed_and_its_dictionary_is_the_json(labelled: Path) -> None:
    import warnings

    from energy_margin.evaluation.metrics import Evaluation

    write_scores(labelled, CAPTURED.astype(float), IN_SUCCESS.astype(float))
    result = evaluate(labelled, resamples=20)
    assert isinstance(result, Evaluation) and result.capture_ap == 1.0
    values = result.to_dict()
    assert list(values)[:5] == ["capture_ap", "capture_ap_window2", "success_ap", "success_ap_first_half", "baselines"]
    assert list(values)[5:8] == ["verdict", "verdict_resamples", "seed"]
    assert Evaluation.from_dict(json.loads(json.dumps(values))).to_dict() == json.loads(json.dumps(values))
    # No verdict, k-hat 2: those keys are absent from the dictionary and None on the object.
    plain = evaluate(labelled, capture_window=2, resamples=0)
    assert plain.verdict is None and plain.capture_ap_window2 is None
    assert not {"verdict", "seed", "capture_ap_window2", "capture_positive_rate_window2"} & set(plain.to_dict())
    # Reading it as the dictionary of earlier releases still works, with a warning naming the attribute.
    with pytest.warns(DeprecationWarning, match=r"use \.capture_ap"):
        assert result["capture_ap"] == 1.0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert "capture_ap" in result and len(result) == len(values) and set(result) == set(values)
