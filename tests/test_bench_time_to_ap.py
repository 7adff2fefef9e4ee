"""benchmarks/time_to_ap.py: its traces, its replay of the adaptive budget and its choice of a budget."""

from __future__ import annotations

import numpy as np
import pytest

from bench_modules import load_benchmark
from energy_margin.analysis.frame import AnalyzerConfig, analyze_frame
from energy_margin.tasks import get_task


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("time_to_ap")


class _Dataset:
    """What the trace reads of a dataset: the task and a frame."""

    def __init__(self, task, frame) -> None:  # type: ignore[no-untyped-def]
        self.task, self._frame = task, frame

    def frame(self, trajectory: int, index: int):  # type: ignore[no-untyped-def]
        return self._frame


@pytest.mark.parametrize(
    ("rule", "tolerance"),
    [("projected", 0.02), ("projected", 0.05), ("window", 0.02), ("projected-reached", 0.05)],
)
def test_the_replayed_rule_stops_where_the_analyzer_stops(bench, rule: str, tolerance: float) -> None:
    task = get_task("pushing")
    trajectory = task.sample_trajectory(np.random.default_rng(4), 3)
    frame, lam = trajectory.initial, task.config.likelihood_lambda
    common = {"friction": trajectory.friction, "drive": trajectory.drive, "seed": 9}
    trace = bench._Trace(_Dataset(task, frame), 0, 0, lam)
    analyze_frame(task, frame, **common, config=AnalyzerConfig(expansions=150), stop=trace, check_every=bench.STEP)
    stopped, _ = analyze_frame(
        task, frame, **common, config=AnalyzerConfig(expansions=150, converge=tolerance, converge_rule=rule)
    )
    assert bench._replay(trace.rows, rule, tolerance, 150) == stopped.expansions
    capture, success, _ = bench._at(trace.rows, stopped.expansions)
    assert (capture, success) == (stopped.capture_score, stopped.success_score)


def test_the_cheapest_budget_holding_every_ap_is_chosen(bench) -> None:
    def entry(seed: int, aps: dict[int, float]) -> dict:
        rows = [
            {"expansions": budget, **{key: value for key in bench.QUESTIONS}, "seconds_per_frame": budget / 1000}
            for budget, value in aps.items()
        ]
        return {"seed": seed, "budgets": rows}

    choosing = entry(1, {50: 0.80, 100: 0.895, 300: 0.90})
    checking = entry(2, {50: 0.9, 100: 0.85, 300: 0.9})
    found = bench.choose([choosing, checking], 1)
    assert found["chosen_expansions"] == 100
    assert found["checks"][0]["holds"] is False
    assert found["checks"][0]["change"]["capture_ap"] == pytest.approx(-0.05)


def test_the_reached_rule_waits_for_a_success_score_above_zero(bench) -> None:
    # Both scores flat from the first check: the projected rule stops at the first check a window back.
    flat = [(n, 0.9, 0.0, n / 1000) for n in range(0, 301, 25)]
    assert bench._replay(flat, "projected", 0.02, 300) == 50
    assert bench._replay(flat, "projected-reached", 0.02, 300) == 300
    # Success leaves 0 at 100 expansions and stays: settled once a window lies past that move.
    moved = [(n, 0.9, 0.0 if n < 100 else 0.4, n / 1000) for n in range(0, 301, 25)]
    assert bench._replay(moved, "projected-reached", 0.02, 300) == 150


def test_a_set_measured_before_a_rule_existed_is_measured_again(bench, tmp_path) -> None:
    import json

    settings = {"task": "pushing", "seeds": [61, 62], "choose": 1, "trajectories": 2}
    every_rule = [{"rule": rule, "tolerance": t} for rule, ts in bench.RULES.items() for t in ts]
    sets = [{"seed": 61, "rules": every_rule}, {"seed": 62, "rules": every_rule[:-1]}]
    path = tmp_path / "found.json"
    path.write_text(json.dumps({"settings": settings, "sets": sets}))
    assert [entry["seed"] for entry in bench._done_sets(path, settings)] == [61]
    with pytest.raises(SystemExit, match="other settings"):
        bench._done_sets(path, {**settings, "trajectories": 3})
