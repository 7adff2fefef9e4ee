"""benchmarks/converge_ap.py: its settings are analyzer settings, its means, one analysis of a copy."""

from __future__ import annotations

from pathlib import Path

import pytest

from bench_modules import load_benchmark
from energy_margin.analysis.frame import AnalyzerConfig


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("converge_ap")


def test_every_setting_is_an_analyzer_configuration(bench) -> None:
    for fields in bench.SETTINGS.values():
        AnalyzerConfig(expansions=bench.EXPANSIONS, continuation=0, **fields)
    assert bench.SETTINGS["defaults"] == {}
    assert set(bench.RECORDED_ONLY) <= set(bench.SETTINGS)


def test_a_mean_row_is_none_where_a_question_has_no_ap(bench) -> None:
    rows = [
        {"capture_ap": 0.9, "capture_ap_window2": 0.8, "success_ap": None, "success_ap_first_half": 0.5,
         "mean_expansions": 300.0},
        {"capture_ap": 1.0, "capture_ap_window2": 0.6, "success_ap": 0.7, "success_ap_first_half": 0.7,
         "mean_expansions": 100.0},
    ]  # fmt: skip
    found = bench.mean_row(rows)
    assert found["capture_ap"] == pytest.approx(0.95)
    assert found["success_ap"] is None
    assert found["mean_expansions"] == pytest.approx(200.0)


def test_an_analysis_of_a_copy_leaves_the_source_unanalysed(bench, tiny_dataset: Path, tmp_path: Path) -> None:
    row = bench._analysed(tiny_dataset, tmp_path / "copy", "converge_0.02", 0, 1, {})
    assert (tmp_path / "copy" / "scores.csv").exists()
    assert not (tiny_dataset / "scores.csv").exists()
    assert 0 < row["mean_expansions"] <= bench.EXPANSIONS
    assert set(bench.QUESTIONS) <= set(row)


def test_changes_are_against_the_whole_budget_run_by_run(bench) -> None:
    def row(value: float) -> dict:
        return {question: value for question in bench.QUESTIONS} | {"mean_expansions": 300.0}

    found = {
        "defaults": {"runs": [row(0.9), row(0.8)], "mean": row(0.85)},
        "converge_0.02": {"runs": [row(0.88), row(0.81)], "mean": row(0.845)},
    }
    changed = bench.with_changes(found)
    assert changed["defaults"]["change"]["capture_ap"] == 0.0
    assert changed["converge_0.02"]["change"]["capture_ap"] == pytest.approx(-0.005)
    assert [run["capture_ap"] for run in changed["converge_0.02"]["change_by_run"]] == pytest.approx([-0.02, 0.01])
