"""benchmarks/time_reproduce.py: the stage sums and the announced duration its results file keeps."""

from __future__ import annotations

import pytest

from bench_modules import load_benchmark


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("time_reproduce")


def test_the_stages_are_summed_by_part(bench) -> None:
    stages = [
        {"stage": "analyze pushing-10 (true states)", "seconds": 2.004, "resumed": False},
        {"stage": "analyze pushing-10 perturbed copy 1/2 (paper protocol)", "seconds": 1.5},
        {"stage": "perturb pushing-10 (2 copies, paper protocol)", "seconds": 0.25},
        {"stage": "report", "seconds": 3.0},
    ]
    figures = bench.stage_figures(stages)
    assert figures["stages_s"] == 6.8 and figures["paper_protocol_stages_s"] == 1.8 and figures["report_stage_s"] == 3.0
    assert figures["stages"][0] == {"stage": "analyze pushing-10 (true states)", "seconds": 2.0}


def test_the_announced_duration_in_minutes(bench) -> None:
    assert bench.announced_minutes("75 s") == 1.2
    assert bench.announced_minutes("27 min") == 27.0
    assert bench.announced_minutes("1.5 h") == 90.0
    assert bench.announced_minutes(None) is None
