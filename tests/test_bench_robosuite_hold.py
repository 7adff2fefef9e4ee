"""benchmarks/robosuite_hold.py: one hold's entry from the example's results and its evaluate text."""

from __future__ import annotations

import pytest

from bench_modules import load_benchmark

KEYS = ("capture_ap", "capture_ap_window2", "success_ap", "success_ap_first_half")


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("robosuite_hold")


def _evaluation(margin: float, best: float, word: str) -> dict:
    verdict = {"baseline": "distance", "difference": margin - best, "low": -0.1, "high": 0.2, "word": word}
    return {
        **dict.fromkeys(KEYS, margin),
        "baselines": {"distance": dict.fromkeys(KEYS, best), "chance": dict.fromkeys(KEYS, 0.4)},
        "verdict": dict.fromkeys(KEYS, verdict),
    }


def test_an_entry_keeps_both_evaluations_the_live_calls_and_the_analysis_time(bench) -> None:
    results = {
        "mujoco": "3.9.0",
        "robosuite": "1.5.2",
        "episodes": [{}] * 40,
        "success_rate": 0.375,
        "timing": {"mean_ms": 46.5, "mean_expansions": 9.8},
        "evaluate": {"analyze": _evaluation(0.635, 0.375, "ahead"), "live": _evaluation(0.458, 0.375, "level")},
    }
    text = "== energy-margin evaluate d\nquestion ...\nruntime per frame: 4.215 +- 2.915 s (physics 0.519 s)\n"
    entry = bench.summary(results, text)
    assert (entry["episodes"], entry["success_rate"], entry["seconds_per_frame"]) == (40, 0.375, 4.215)
    assert (entry["live_mean_ms"], entry["live_mean_expansions"]) == (46.5, 9.8)
    early = entry["analyze"]["success_ap_first_half"]
    assert (early["margin"], early["baseline"], early["baseline_ap"], early["word"]) == (
        0.635,
        "distance",
        0.375,
        "ahead",
    )
    assert entry["live"]["success_ap_first_half"]["margin"] == 0.458
    assert entry["live"]["success_ap_first_half"]["word"] == "level"
    assert bench.summary(results, None)["seconds_per_frame"] is None
