"""benchmarks/bench_integrations.py: the latency summary its results file keeps."""

from __future__ import annotations

import pytest

from bench_modules import load_benchmark


def test_the_summary_counts_the_calls_within_the_budget() -> None:
    bench = load_benchmark("bench_integrations")
    margins = [{"ms": ms, "expansions": 10 * k} for k, ms in enumerate([9.0, 10.0, 10.5, 11.5])]
    row = bench.summary("tree", margins, 10.0)
    assert row["calls"] == 4 and row["max_ms"] == 11.5 and row["expansions_mean"] == 15.0
    assert row["within_budget"] == 0.5 and row["within_1_1_budget"] == 0.75
    assert row["mean_ms"] == pytest.approx(10.25)
    unbounded = bench.summary("learned", margins, None)
    assert unbounded["within_budget"] is None and "| - | - |" in bench.describe(unbounded)
