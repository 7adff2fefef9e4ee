"""benchmarks/generality_examples.py: the table's cells and the order of its rows."""

from __future__ import annotations

import pytest

from bench_modules import load_benchmark


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("generality_examples")


def _verdict(word: str, difference: float | None) -> dict:
    low = None if difference is None else difference - 0.01
    high = None if difference is None else difference + 0.01
    return {"word": word, "difference": difference, "low": low, "high": high}


def test_cells_say_the_ap_and_the_verdict(bench) -> None:
    assert bench.cell(0.98123, _verdict("ahead", 0.084)) == "0.981 (**ahead** +0.084 [+0.074, +0.094])"
    assert bench.cell(0.5, _verdict("level", -0.002)) == "0.500 (level -0.002 [-0.012, +0.008])"
    assert bench.cell(1.0, _verdict("level", None)) == "1.000"
    assert bench.cell(0.9) == "0.900"
    assert bench.cell(None, _verdict("level", 0.0)) == "n/a"


def test_rows_follow_the_tables_order_then_the_baselines(bench) -> None:
    questions = ("capture k̂ = 0", "success, first 5")

    def row(settings: str, value: float) -> dict:
        return {
            "settings": settings,
            "ap": dict.fromkeys(questions, value),
            "verdict": {question: _verdict("ahead", 0.1) for question in questions},
        }

    found = {
        "rows": [
            row("the file's (λ 5)", 0.9),
            row("derived (λ 3.46)", 0.8),
            row("calibrated (λ 0.5 by fold)", 0.7),
            row("fixed defaults (λ 5)", 0.6),
        ],
        "baselines": {"current_state": dict.fromkeys(questions, 1.0), "distance": dict.fromkeys(questions, None)},
    }
    rows = bench.table_rows("jaco", found)
    assert [r["settings"] for r in rows] == [
        "the file's (λ 5)",
        "fixed defaults (λ 5)",
        "derived (λ 3.46)",
        "calibrated (λ 0.5 by fold)",
        "baseline: current state",
        "baseline: distance",
    ]
    assert [r["example"] for r in rows] == ["`jaco`", "", "", "", "", ""]
    assert rows[1]["q0"] == "0.600 (**ahead** +0.100 [+0.090, +0.110])"
    assert (rows[4]["q1"], rows[5]["q1"]) == ("1.000", "n/a")
    assert bench.EXAMPLES.keys() >= {"pushing", "record", "panda_tray"}
