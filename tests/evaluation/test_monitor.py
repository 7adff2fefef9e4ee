from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from energy_margin.data.dataset import load_dataset
from energy_margin.data.scores_file import UNGATED_COLUMNS
from energy_margin.errors import EnergyMarginError, InvalidParameterError
from energy_margin.evaluation.monitor import (
    LiveAlarm,
    MonitorCalibration,
    alarm_frames,
    calibrate_grid,
    calibrate_monitor,
    conformal_rank,
    load_calibration,
    monitored_grids,
    worst_scores,
    write_calibration,
)
from energy_margin.evaluation.monitor_report import (
    alarm_measures,
    compare_monitors,
    evaluate_monitor,
    failure_frames,
    format_table,
)
from score_files import write_scores

# ---------------------------------------------------------------- the conformal guarantee


def _realised_false_alarms(
    n: int, alpha: float, *, draws: int = 2000, seed: int = 0, persistence: int = 1
) -> np.ndarray:
    """Realised false-alarm rate on 200 fresh successes per calibration draw of n successes (T x 6 grids)."""
    rng = np.random.default_rng(seed)
    rates = np.empty(draws)
    for draw in range(draws):
        # Exchangeable successes: every roll-out's frames drawn from one distribution, a drift over time.
        calibration = rng.normal(size=(n, 6)) + np.linspace(0.0, 1.0, 6)
        test = rng.normal(size=(200, 6)) + np.linspace(0.0, 1.0, 6)
        found = calibrate_grid(calibration, np.ones(n, dtype=bool), alpha=alpha, start_frame=1, persistence=persistence)
        alarms = alarm_frames(test, found.threshold, start_frame=1, persistence=persistence)
        rates[draw] = float((alarms >= 0).mean())
    return rates


@pytest.mark.parametrize(("n", "alpha", "persistence"), [(19, 0.05, 1), (25, 0.1, 1), (40, 0.1, 1), (25, 0.1, 3)])
def test_exchangeable_successes_alarm_at_most_alpha(n: int, alpha: float, persistence: int) -> None:
    rates = _realised_false_alarms(n, alpha, persistence=persistence)
    promised = conformal_rank(n, alpha) / (n + 1)
    assert promised <= alpha
    # The mean over calibration draws is j / (n + 1) for continuous scores: at most alpha, and not far below.
    assert rates.mean() <= alpha + 0.005
    assert rates.mean() == pytest.approx(promised, abs=0.005)


def test_the_rank_is_the_floor_of_n_plus_one_alpha() -> None:
    assert conformal_rank(19, 0.05) == 1
    assert conformal_rank(25, 0.1) == 2  # ceil would take 3: 3 / 26 > 0.1
    assert conformal_rank(9, 0.1) == 1
    assert conformal_rank(3, 0.9) == 3  # never past the largest


def test_too_few_successes_are_refused_in_one_line() -> None:
    with pytest.raises(InvalidParameterError, match=r"^alpha 0.05 needs at least 19 successful") as caught:
        conformal_rank(18, 0.05)
    assert caught.value.parameter == "alpha"
    assert "\n" not in str(caught.value)
    grid = np.zeros((30, 4))
    success = np.zeros(30, dtype=bool)
    success[:8] = True  # 8 successes: alpha 0.1 needs 9, the 22 failures do not count
    with pytest.raises(InvalidParameterError, match="needs at least 9 successful calibration roll-outs"):
        calibrate_grid(grid, success, alpha=0.1)
    for alpha in (0.0, 1.0, -0.1):
        with pytest.raises(InvalidParameterError, match=r"^alpha must be"):
            conformal_rank(100, alpha)


def test_the_threshold_ignores_failures_and_frames_before_the_start() -> None:
    grid = np.array([[0.0, 0.9, 0.8], [0.0, 0.5, 0.7], [0.0, 0.0, 0.0], [0.0, 0.6, 0.95]])
    success = np.array([True, True, False, True])
    np.testing.assert_array_equal(worst_scores(grid, start_frame=1), [0.8, 0.5, 0.0, 0.6])
    found = calibrate_grid(grid, success, alpha=0.5, start_frame=1)  # n = 3, j = floor(2) = 2
    assert (found.rank, found.n_successes, found.n_trajectories) == (2, 3, 4)
    assert found.threshold == 0.6
    assert found.fires(0.59) and not found.fires(0.6)
    with pytest.raises(InvalidParameterError, match=r"^start_frame"):
        worst_scores(grid, start_frame=3)


def test_the_alarm_fires_at_the_first_monitored_frame_below_the_threshold() -> None:
    grid = np.array([[0.1, 0.9, 0.3, 0.2], [0.9, 0.9, 0.9, 0.9], [0.1, 0.1, 0.9, 0.1]])
    np.testing.assert_array_equal(alarm_frames(grid, 0.5), [0, -1, 0])
    np.testing.assert_array_equal(alarm_frames(grid, 0.5, start_frame=1), [2, -1, 1])
    np.testing.assert_array_equal(alarm_frames(grid, 0.1, start_frame=2), [-1, -1, -1])


def test_persistence_waits_for_that_many_monitored_frames_below() -> None:
    grid = np.array([[0.1, 0.9, 0.3, 0.2], [0.9, 0.9, 0.9, 0.9], [0.1, 0.1, 0.9, 0.1]])
    np.testing.assert_array_equal(alarm_frames(grid, 0.5, persistence=2), [2, -1, 1])
    np.testing.assert_array_equal(alarm_frames(grid, 0.5, persistence=3), [3, -1, 3])
    np.testing.assert_array_equal(alarm_frames(grid, 0.5, start_frame=1, persistence=2), [3, -1, 3])
    # The nonconformity is the persistence-th smallest monitored score: it fires exactly when that is below.
    np.testing.assert_array_equal(worst_scores(grid, persistence=2), [0.2, 0.9, 0.1])
    with pytest.raises(InvalidParameterError, match=r"^persistence"):
        alarm_frames(grid, 0.5, start_frame=2, persistence=3)
    with pytest.raises(InvalidParameterError, match=r"^persistence"):
        worst_scores(grid, persistence=0)


def test_a_success_at_zero_for_one_frame_leaves_persistence_two_able_to_fire() -> None:
    # Success 0 scores 0 at one frame: with persistence 1 the threshold is 0 and nothing fires.
    successes = np.array([[0.0, 0.0, 0.7, 0.9], [0.0, 0.4, 0.8, 0.9], [0.0, 0.5, 0.6, 1.0]] * 4)
    labels = np.ones(len(successes), dtype=bool)
    first = calibrate_grid(successes, labels, alpha=0.1, start_frame=1)
    assert first.threshold == 0.0 and not first.can_fire
    second = calibrate_grid(successes, labels, alpha=0.1, start_frame=1, persistence=2)
    assert second.threshold == pytest.approx(0.6) and second.can_fire and second.persistence == 2
    failure = np.array([[0.0, 0.0, 0.0, 0.2]])
    assert alarm_frames(failure, second.threshold, start_frame=1, persistence=2)[0] == 2
    # A distance threshold of 0 m (or below) can still be undercut.
    assert calibrate_grid(successes - 1.0, labels, alpha=0.1, start_frame=1, scorer="distance").can_fire


# ---------------------------------------------------------------- failure frame and lead time


def test_failure_frames_follow_the_capture_labels() -> None:
    captured = np.array(
        [
            [True, True, False, True, False, False],  # lost for good from frame 4
            [False, False, False, False, False, False],  # never captured: frame 0
            [True, True, True, True, True, True],  # failed the success region only: the last frame
            [True, False, False, False, False, False],  # a success: none
        ]
    )
    success = np.array([False, False, False, True])
    np.testing.assert_array_equal(failure_frames(captured, success), [4, 0, 5, -1])


def test_lead_time_detection_and_false_alarms_by_hand() -> None:
    times = np.tile(np.arange(6) * 0.25, (5, 1))
    failures = np.array([4, 2, 5, -1, -1])
    alarms = np.array([1, 3, -1, 2, -1])  # 0.75 s early, 0.25 s late, missed; one false alarm in two
    found = alarm_measures(alarms, failures, times)
    assert found["detection_rate"] == pytest.approx(2 / 3)
    assert found["early_detection_rate"] == pytest.approx(1 / 3)
    assert found["lead_time_s"] == pytest.approx((0.75 - 0.25) / 2)
    assert found["false_alarm_rate"] == pytest.approx(0.5)
    none = alarm_measures(np.array([-1, -1]), np.array([-1, -1]), times[:2])
    assert none == {"detection_rate": None, "early_detection_rate": None, "lead_time_s": None, "false_alarm_rate": 0.0}


# ---------------------------------------------------------------- datasets

CAPTURED = np.array([[True, True, True], [True, False, False]])
IN_SUCCESS = np.array([[False, True, True], [False, False, False]])


@pytest.fixture
def labelled(tiny_dataset: Path, rewrite_frames: Callable[..., None]) -> Path:
    """The tiny dataset: trajectory 0 succeeds, trajectory 1 fails at frame 1; hand-made scores."""
    rewrite_frames(
        tiny_dataset,
        captured=CAPTURED,
        in_success=IN_SUCCESS,
        frame_time=np.array([[0.0, 0.5, 1.0], [0.0, 0.5, 1.0]]),
    )
    capture = np.array([[0.9, 0.8, 0.7], [0.6, 0.3, 0.1]])
    write_scores(tiny_dataset, capture, np.array([[0.5, 0.6, 0.9], [0.2, 0.1, 0.0]]))
    return tiny_dataset


def test_calibrate_and_evaluate_a_dataset(labelled: Path) -> None:
    found = calibrate_monitor(labelled, alpha=0.5, score="min", start_frame=1)
    # One success (trajectory 0): its worst min(capture, success) over frames 1, 2 is 0.6.
    assert (found.threshold, found.n_successes, found.task, found.dataset_seed) == (0.6, 1, "pushing", 0)
    result = evaluate_monitor(found, labelled, resamples=200, seed=3)
    # Trajectory 1 alarms at frame 1 (min 0.1 < 0.6), its failure frame 1: detected, lead 0 s.
    assert (result.detection_rate, result.early_detection_rate, result.lead_time_s) == (1.0, 1.0, 0.0)
    assert result.false_alarm_rate == 0.0
    assert (result.n_failed, result.n_successful, result.resamples, result.seed) == (1, 1, 200, 3)
    assert result.detection_rate_low == 1.0 and result.false_alarm_rate_high == 0.0
    with pytest.raises(InvalidParameterError, match="needs at least 19"):
        calibrate_monitor(labelled, alpha=0.05)


def test_a_capture_alarm_watches_the_trees_own_capture_score(labelled: Path) -> None:
    # The success's frame 1 was out of its region for a moment: gated, its capture is 0 there.
    gated = np.array([[0.9, 0.0, 0.7], [0.6, 0.0, 0.0]])
    tree = np.array([[0.9, 0.8, 0.7], [0.6, 0.3, 0.1]])
    success = np.array([[0.5, 0.6, 0.9], [0.2, 0.1, 0.0]])
    write_scores(labelled, gated, success, tree_capture=tree)
    assert calibrate_monitor(labelled, alpha=0.5, score="capture").threshold == 0.7  # the tree's worst
    assert calibrate_monitor(labelled, alpha=0.5, score="min").threshold == 0.5
    np.testing.assert_array_equal(monitored_grids(load_dataset(labelled), labelled)["capture"], tree)
    # A file written before the tree's own score was kept: the gated score is all there is.
    write_scores(labelled, gated, success, columns=UNGATED_COLUMNS)
    assert calibrate_monitor(labelled, alpha=0.5, score="capture").threshold == 0.0


def test_compare_reports_margin_then_distance(labelled: Path, copy_dataset: Callable[[str], Path]) -> None:
    result = compare_monitors(labelled, labelled, alphas=(0.5,), resamples=50)
    assert [entry["scorer"] for entry in result.evaluations] == ["margin", "distance"]
    assert result.calibration_seed == 0 and result.test_seed == 0
    text = format_table(result)
    assert "margin" in text and "distance" in text
    assert "cannot fire" not in text
    json.dumps(result.to_dict())


def test_the_table_says_when_the_margin_alarm_cannot_fire(labelled: Path) -> None:
    # The success (trajectory 0) scores a capture of 0.7 at worst, its success score 0.5: from frame 0
    # with score "min" the threshold is 0.5. Scores of 0 in the success make it 0: rewrite them.
    write_scores(labelled, np.array([[0.9, 0.0, 0.7], [0.6, 0.3, 0.1]]), np.array([[0.5, 0.6, 0.9], [0.2, 0.1, 0.0]]))
    result = compare_monitors(labelled, labelled, alphas=(0.5,), score="min", resamples=20)
    assert [entry["can_fire"] for entry in result.evaluations] == [False, True]
    assert "the margin alarm at alpha 0.5 cannot fire: its threshold is 0" in format_table(result)
    two = compare_monitors(labelled, labelled, alphas=(0.5,), score="min", persistence=2, resamples=20)
    assert two.evaluations[0]["can_fire"] and two.evaluations[0]["threshold"] == 0.5
    assert "min 0+ x2" in format_table(two)  # the watched score, from frame 0, at the second frame below


def test_a_margin_calibration_needs_scores(tiny_dataset: Path) -> None:
    with pytest.raises(EnergyMarginError, match=r"scores\.csv"):
        calibrate_monitor(tiny_dataset, alpha=0.5)
    # The distance baseline needs none.
    assert calibrate_monitor(tiny_dataset, alpha=0.9, scorer="distance").scorer == "distance"


def test_a_calibration_file_round_trips(tmp_path: Path) -> None:
    grid = np.linspace(0.0, 1.0, 40).reshape(20, 2)
    first = calibrate_grid(grid, np.ones(20, dtype=bool), alpha=0.05)
    second = calibrate_grid(grid, np.ones(20, dtype=bool), alpha=0.1)
    path = tmp_path / "alarm.json"
    write_calibration(path, [first, second])
    assert load_calibration(path, alpha=0.1) == second
    with pytest.raises(EnergyMarginError, match=r"holds 2 calibrations \(alphas: 0.05, 0.1\); pick one by its alpha"):
        load_calibration(path)
    with pytest.raises(InvalidParameterError, match=r"^alpha 0.2 picks no single calibration"):
        load_calibration(path, alpha=0.2)
    write_calibration(path, [first])
    assert load_calibration(path) == first
    data = json.loads(path.read_text())
    data["version"] = 99
    path.write_text(json.dumps(data))
    with pytest.raises(EnergyMarginError, match="version 99"):
        load_calibration(path)
    path.write_text("{}")
    with pytest.raises(EnergyMarginError, match="not a monitor calibration file"):
        load_calibration(path)
    assert isinstance(first, MonitorCalibration)


# ---------------------------------------------------------------- live


def _calibration(**changes: object) -> MonitorCalibration:
    settings: dict[str, object] = {
        "threshold": 0.3,
        "alpha": 0.1,
        "rank": 1,
        "n_successes": 9,
        "n_trajectories": 12,
        "scorer": "margin",
        "score": "min",
        "start_frame": 1,
    }
    settings.update(changes)
    return MonitorCalibration.from_dict(settings)


def test_the_live_alarm_watches_from_the_start_frame_and_stays_raised() -> None:
    alarm = LiveAlarm(_calibration())
    # Call 0 is not monitored; call 2's min(capture, success) = 0.2 < 0.3 fires; it stays raised.
    seen = [alarm.update(c, s) for c, s in [(0.0, 0.0), (0.9, 0.4), (0.2, 0.9), (0.9, 0.9)]]
    assert seen == [False, False, True, True]
    assert alarm.fired_at == 2
    alarm.reset()
    assert alarm.update(0.9, 0.9) is False and alarm.fired_at is None
    success_only = LiveAlarm(_calibration(score="success", start_frame=0))
    assert success_only.update(0.0, 0.5) is False and success_only.update(0.5, 0.1) is True
    # With persistence 2 the second monitored call below the threshold raises it, not the first.
    twice = LiveAlarm(_calibration(persistence=2))
    seen = [twice.update(c, s) for c, s in [(0.0, 0.0), (0.2, 0.9), (0.9, 0.9), (0.1, 0.1), (0.9, 0.9)]]
    assert seen == [False, False, False, True, True] and twice.fired_at == 3
    twice.reset()
    assert twice.below == 0 and twice.update(0.0, 0.0) is False
    with pytest.raises(InvalidParameterError, match=r"^calibration watches the distance baseline"):
        LiveAlarm(_calibration(scorer="distance"))
    with pytest.raises(InvalidParameterError, match=r"^calibration has threshold 0, .* could never fire"):
        LiveAlarm(_calibration(threshold=0.0))
