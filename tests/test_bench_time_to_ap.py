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


@pytest.mark.parametrize(("rule", "tolerance"), [("projected", 0.02), ("projected", 0.05), ("window", 0.02)])
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
