"""benchmarks/unseen_sets.py: its analyses are analyzer settings and each change is against its own reference."""

from __future__ import annotations

import pytest

from bench_modules import load_benchmark
from energy_margin.analysis.frame import AnalyzerConfig


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("unseen_sets")


def test_every_analysis_is_an_analyzer_configuration(bench) -> None:
    for fields in bench.ANALYSES.values():
        AnalyzerConfig(expansions=300, continuation=0, **fields)
    for spec in bench.SETS.values():
        assert {analysis for analysis, _ in spec["runs"]} <= set(bench.ANALYSES)
        assert spec["runs"][0][1] == 0


def test_changes_pair_a_run_with_its_sets_reference_of_the_same_seed(bench) -> None:
    def row(name: str, analysis: str, seed: int, value: float, reference: bool) -> dict:
        aps = {question: value for question in bench.QUESTIONS}
        return {"set": name, "analysis": analysis, "seed": seed, "reference": reference, **aps}

    rows = bench.with_changes(
        [
            row("a", "whole budget", 0, 0.9, True),
            row("a", "whole budget", 1, 0.8, True),
            row("a", "converge 0.02", 1, 0.7, False),
            row("a", "converge 0.01", 2, 0.6, False),
            row("b", "whole budget", 0, 0.5, True),
            row("b", "converge 0.02", 0, 0.55, False),
        ]
    )
    changes = [r["capture_ap_window2_change"] for r in rows]
    # Seed 1 against the seed-1 reference; seed 2 (no reference of its own) against seed 0's; b against b.
    assert changes == pytest.approx([0.0, 0.0, -0.1, -0.3, 0.0, 0.05])


def test_a_missing_ap_gives_no_change(bench) -> None:
    aps = {question: 0.5 for question in bench.QUESTIONS}
    rows = bench.with_changes(
        [
            {"set": "a", "seed": 0, "reference": True, **aps},
            {"set": "a", "seed": 0, "reference": False, **aps, "success_ap": None},
        ]
    )
    assert rows[1]["success_ap_change"] is None
    assert rows[1]["capture_ap_change"] == 0.0


def test_a_run_key_names_the_analysis_and_the_seed(bench) -> None:
    assert bench.run_key({"analysis": "converge 0.02", "seed": 1}) == "converge_0.02_seed1"
