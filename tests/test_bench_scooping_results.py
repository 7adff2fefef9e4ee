"""benchmarks/scooping_results.py: its λ grid holds the task's own, and one evaluation row."""

from __future__ import annotations

from pathlib import Path

import pytest

from bench_modules import load_benchmark
from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.run import analyze
from energy_margin.tasks import get_task


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("scooping_results")


def test_the_grid_holds_the_tasks_own_lambda(bench) -> None:
    assert get_task("scooping").config.likelihood_lambda in bench.LAMBDAS
    assert len(set(bench.LAMBDAS)) == len(bench.LAMBDAS)


def test_an_evaluation_row_has_every_question_and_baseline(bench, tiny_dataset: Path) -> None:
    analyze(tiny_dataset, AnalyzerConfig(expansions=5, continuation=0), seed=0, progress=False)
    row = bench.evaluation_row(tiny_dataset)
    assert set(bench.QUESTIONS) <= set(row)
    assert {"current_state", "chance"} <= set(row["baselines"])
    assert set(row["baselines"]["chance"]) == set(bench.QUESTIONS)
    assert row["runtime_per_frame_s"] > 0.0
    assert 0.0 <= row["capture_positive_rate"] <= 1.0
