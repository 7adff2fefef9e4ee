"""benchmarks/paper_values.py: the paper's values as the report prints them, and the kept file is current."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from bench_modules import load_benchmark
from energy_margin.report.paper import PAPER_FIG_2, PAPER_TABLE_I

KEPT = Path(__file__).resolve().parents[1] / "docs" / "figures" / "paper.json"


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("paper_values")


def test_spreads_become_mean_and_std(bench) -> None:
    found = bench.as_json()
    mean, std = PAPER_TABLE_I["scooping"]["capture_ap_perturbed"]
    assert found["table_1"]["scooping"]["capture_ap_perturbed"] == {"mean": mean, "std": std}
    assert found["table_1"]["pushing"]["capture_ap"] == PAPER_TABLE_I["pushing"]["capture_ap"]
    assert found["fig_2"]["10"]["runtime"]["mean"] == PAPER_FIG_2[10]["runtime"][0]


def test_the_kept_file_is_what_the_report_prints(bench) -> None:
    assert json.loads(KEPT.read_text(encoding="utf-8")) == bench.as_json()
