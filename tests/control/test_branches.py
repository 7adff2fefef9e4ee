"""The branch study: branches replay the plant exactly, scores and outcomes line up, summaries count right."""

from __future__ import annotations

import numpy as np
import pytest

from energy_margin.control.branches import BranchState, BranchStudy, branch_study, concordance
from energy_margin.control.disturbances import get_disturbance
from energy_margin.control.mppi import ControllerConfig
from energy_margin.errors import InvalidParameterError
from energy_margin.tasks import get_task


def _state(outcomes: list[bool], task: list[float], *, time: float = 0.5, episode: int = 0) -> BranchState:
    return BranchState(episode, time, outcomes[0], np.array(outcomes), {"task": np.array(task, dtype=float)})


def test_concordance_counts_pairs_of_split_states_with_ties_half() -> None:
    states = [
        _state([True, False, False], [3.0, 1.0, 3.0]),  # pairs: 3>1 win, 3=3 tie
        _state([True, True], [0.0, 1.0]),  # not split: ignored
        _state([False, True], [2.0, 1.0]),  # pair: 1<2 loss
    ]
    value, pairs = concordance(states, "task")
    assert pairs == 3
    assert value == pytest.approx((1.0 + 0.5 + 0.0) / 3)
    assert np.isnan(concordance([states[1]], "task")[0])


def test_summary_counts_splits_rescues_and_reachable_episodes() -> None:
    states = [
        _state([False, True, False], [0.0, 1.0, 0.0], episode=0, time=0.2),
        _state([False, False, False], [0.0, 0.0, 0.0], episode=0, time=0.4),
        _state([True, True, False], [1.0, 1.0, 0.0], episode=1, time=0.2),
        _state([False, False, False], [0.0, 0.0, 0.0], episode=2, time=0.2),
    ]
    study = BranchStudy({"task": "pushing"}, states, np.array([False, True, False]))
    summary = study.summary()
    assert summary["episodes"] == 3
    assert summary["split_states"] == 2
    assert summary["failures"] == 2
    assert summary["rescuable_failures"] == 1
    assert summary["reachable_success_rate"] == pytest.approx(2 / 3)
    assert summary["concordance_task"] == pytest.approx(1.0)
    first = summary["per_time"][0]
    assert first["time"] == 0.2 and first["states"] == 3 and first["split"] == 2
    assert first["rescued"] == 1 and first["spoiled"] == 1


def test_branch_zero_replays_the_nominal_run_and_the_study_is_deterministic() -> None:
    task = get_task("pushing")
    config = ControllerConfig(samples=4, horizon=2)
    kwargs = {
        "n_objects": 2,
        "episodes": 2,
        "disturbance": get_disturbance("hard"),
        "seed": 3,
        "decision_times": [0.3, 0.9],
        "config": config,
        "scores": ("task",),
    }
    study = branch_study(task, **kwargs)
    assert len(study.states) == 4
    # These episodes end one in success and one in failure: both kinds of replay are checked.
    assert sorted({state.nominal_success for state in study.states}) == [False, True]
    for state in study.states:
        # Branch 0 is the plan itself (no deviation): it must end exactly as the nominal run.
        assert bool(state.outcomes[0]) == state.nominal_success
        assert state.outcomes.shape == (4,) and state.scores["task"].shape == (4,)
    again = branch_study(task, **kwargs)
    for first, second in zip(study.states, again.states, strict=True):
        np.testing.assert_array_equal(first.outcomes, second.outcomes)
        np.testing.assert_array_equal(first.scores["task"], second.scores["task"])


def test_bad_arguments_are_named() -> None:
    task = get_task("pushing")
    common = {"n_objects": 2, "episodes": 1, "disturbance": get_disturbance("none"), "seed": 0}
    with pytest.raises(InvalidParameterError, match="scores"):
        branch_study(task, decision_times=[0.5], scores=("distance",), **common)
    with pytest.raises(InvalidParameterError, match="decision_times"):
        branch_study(task, decision_times=[], **common)
