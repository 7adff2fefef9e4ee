from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from energy_margin.data.generate import generate_dataset
from energy_margin.errors import InvalidParameterError
from energy_margin.evaluation import monitor
from energy_margin.evaluation.monitor_report import compare_monitors, format_table
from energy_margin.evaluation.monitor_select import AlarmChoice, select_alarm, select_alarms
from score_files import write_scores

# Trajectory 0 succeeds; trajectory 1 fails from frame 1 (its capture label is lost there).
CAPTURED = np.array([[True, True, True], [True, False, False]])
IN_SUCCESS = np.array([[False, True, True], [False, False, False]])
# The failure's capture score drops below the success's worst (0.7) at frame 0; its success score
# stays above the success's worst (0.5) until frame 2, after the failure frame.
CAPTURE = np.array([[0.9, 0.8, 0.7], [0.6, 0.3, 0.1]])
SUCCESS = np.array([[0.5, 0.6, 0.9], [0.7, 0.7, 0.0]])


@pytest.fixture
def selection(tiny_dataset: Path, rewrite_frames: Callable[..., None]) -> Path:
    rewrite_frames(
        tiny_dataset,
        captured=CAPTURED,
        in_success=IN_SUCCESS,
        frame_time=np.array([[0.0, 0.5, 1.0], [0.0, 0.5, 1.0]]),
    )
    write_scores(tiny_dataset, CAPTURE, SUCCESS)
    return tiny_dataset


def test_the_choice_detects_the_failure_earliest(selection: Path) -> None:
    choice = select_alarm(selection, alpha=0.5)
    assert isinstance(choice, AlarmChoice)
    # capture from frame 0 fires at frame 0 (lead 0.5 s); success only at frame 2; min at frame 1 (lead 0).
    assert (choice.score, choice.start_frame, choice.persistence) == ("capture", 0, 1)
    assert (choice.early_detection_rate, choice.lead_time_s) == (1.0, 0.5)
    assert (choice.selection_dataset, choice.selection_seed, choice.alpha) == (str(selection), 0, 0.5)
    tried = {(row["score"], row["start_frame"], row["persistence"]): row for row in choice.candidates}
    # Three scores; from frame 0 persistence 1 to 3, from frame 1 (K / 2) 1 to 2.
    assert len(tried) == 15
    assert tried[("success", 0, 1)]["early_detection_rate"] == 0.0
    assert tried[("min", 0, 1)]["lead_time_s"] == 0.0
    json.dumps(choice.to_dict())


def test_ties_go_to_the_earlier_frame_and_smaller_persistence(selection: Path, rewrite_frames) -> None:
    # Every score of the failure below every score of the success: every candidate detects at its
    # first monitored frame, so the lead decides (frame 0) and then the smaller persistence.
    write_scores(selection, np.array([[0.9, 0.9, 0.9], [0.1, 0.1, 0.1]]), np.array([[0.9, 0.9, 0.9], [0.1, 0.1, 0.1]]))
    choice = select_alarm(selection, alpha=0.5, max_persistence=2)
    assert (choice.score, choice.start_frame, choice.persistence) == ("success", 0, 1)
    assert max(row["persistence"] for row in choice.candidates) == 2


def test_a_selection_set_with_too_few_successes_is_refused(selection: Path) -> None:
    with pytest.raises(InvalidParameterError, match=r"^alpha 0.1 needs at least 9 successful calibration roll-outs"):
        select_alarm(selection, alpha=0.1)
    with pytest.raises(InvalidParameterError, match=r"^max_persistence"):
        select_alarm(selection, alpha=0.5, max_persistence=0)


def test_compare_with_a_selection_set_calibrates_the_choice(selection: Path, tmp_path: Path) -> None:
    calibration = tmp_path / "calibration"
    shutil.copytree(selection, calibration)
    result = compare_monitors(calibration, calibration, alphas=(0.5,), selection=selection, resamples=20)
    margin = result.evaluations[0]
    assert (margin["score"], margin["start_frame"], margin["persistence"]) == ("capture", 0, 1)
    assert [choice["scorer"] for choice in result.choices] == ["margin", "distance"]
    assert "candidates" not in result.choices[0]
    assert f"chosen on {selection} (seed 0)" in format_table(result)
    # Without one, the given settings and no choices.
    plain = compare_monitors(selection, selection, alphas=(0.5,), resamples=20)
    assert plain.choices == [] and plain.evaluations[0]["score"] == "success"
    with pytest.raises(InvalidParameterError, match=r"^selection is the calibration set"):
        compare_monitors(calibration, selection, alphas=(0.5,), selection=calibration / ".." / "calibration")


@pytest.mark.parametrize("scorer", ["margin", "distance"])
def test_several_alphas_load_the_set_and_build_its_grids_once(
    selection: Path, monkeypatch: pytest.MonkeyPatch, scorer: str
) -> None:
    alphas = (0.5, 0.6)
    one_by_one = [select_alarm(selection, alpha=alpha, scorer=scorer) for alpha in alphas]
    built: list[str] = []
    for name in ("load_scores", "distance_scores"):
        original = getattr(monitor, name)

        def counted(*args, _original=original, _name=name, **kwargs):  # type: ignore[no-untyped-def]
            built.append(_name)
            return _original(*args, **kwargs)

        monkeypatch.setattr(monitor, name, counted)
    together = select_alarms(selection, alphas=alphas, scorer=scorer)
    assert [choice.to_dict() for choice in together] == [choice.to_dict() for choice in one_by_one]
    assert built == ["load_scores" if scorer == "margin" else "distance_scores"]
    with pytest.raises(InvalidParameterError, match=r"^alpha 0.1 needs"):
        select_alarms(selection, alphas=(0.5, 0.1), scorer=scorer)


# Four successes and a failure (trajectory 4, its capture label lost from frame 1). Two successes
# score a capture of 0 at frame 0: watching capture from frame 0 at persistence 1 the conformal
# threshold at alpha 0.7 (rank 3 of 4) is still 0.8 on this set, but two floor successes of a
# needed 1.75 leave no room: on a set with one more such success it could not fire.
FLOOR_CAPTURE = np.array([[0.0, 0.9, 0.9], [0.0, 0.9, 0.9], [0.8, 0.9, 0.9], [0.8, 0.9, 0.9], [0.5, 0.1, 0.0]])
FLOOR_SUCCESS = np.array([[0.5, 0.5, 0.5]] * 4 + [[0.9, 0.9, 0.9]])


@pytest.fixture
def floor_selection(tmp_path: Path, rewrite_frames: Callable[..., None]) -> Path:
    out = tmp_path / "five"
    generate_dataset("pushing", out=out, n_objects=2, n_trajectories=5, n_frames=3, seed=0)
    rewrite_frames(
        out,
        captured=np.array([[True, True, True]] * 4 + [[True, False, False]]),
        in_success=np.array([[False, True, True]] * 4 + [[False, False, False]]),
        frame_time=np.array([[0.0, 0.5, 1.0]] * 5),
    )
    write_scores(out, FLOOR_CAPTURE, FLOOR_SUCCESS)
    return out


def test_a_candidate_without_room_above_the_floor_is_passed_over(floor_selection: Path) -> None:
    choice = select_alarm(floor_selection, alpha=0.7)
    tried = {(row["score"], row["start_frame"], row["persistence"]): row for row in choice.candidates}
    edge = tried[("capture", 0, 1)]
    # The best by detection and lead (0.5 s), yet ineligible: 2 successes at the floor >= (4 + 1) 0.7 / 2.
    assert (edge["early_detection_rate"], edge["lead_time_s"]) == (1.0, 0.5)
    assert (edge["floor_successes"], edge["eligible"]) == (2, False)
    # Persistence 2 skips the floor frame: no success there, detected at the failure frame (lead 0).
    assert (choice.score, choice.start_frame, choice.persistence, choice.eligible) == ("capture", 0, 2, True)
    assert (choice.early_detection_rate, choice.lead_time_s) == (1.0, 0.0)
    assert tried[("capture", 0, 2)]["floor_successes"] == 0


def test_with_no_eligible_candidate_the_best_of_all_is_taken_and_said(selection: Path, tmp_path: Path) -> None:
    # The one success scores 0 everywhere: every margin candidate's threshold is the floor.
    write_scores(selection, np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]), np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]))
    choice = select_alarm(selection, alpha=0.5)
    assert not choice.eligible and not any(row["eligible"] for row in choice.candidates)
    assert choice.early_detection_rate == 0.0
    calibration = tmp_path / "calibration"
    shutil.copytree(selection, calibration)
    result = compare_monitors(calibration, calibration, alphas=(0.5,), selection=selection, resamples=20)
    assert "no margin alarm at alpha 0.5 left room above the score's floor" in format_table(result)
    # The distance baseline's scores have no floor: every candidate is eligible.
    assert all(row["eligible"] for row in select_alarm(selection, alpha=0.5, scorer="distance").candidates)
