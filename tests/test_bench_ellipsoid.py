"""benchmarks/bench_ellipsoid.py: a row times real fits and counts their iterations."""

from __future__ import annotations

import numpy as np

from bench_modules import load_benchmark


def test_a_row_holds_the_fits_times_and_iterations() -> None:
    row = load_benchmark("bench_ellipsoid").time_case(np.random.default_rng(0), 2, 10, 1e-2)
    assert row["sets"] == 200 and (row["d"], row["n"], row["tol"]) == (2, 10, 1e-2)
    assert 0 < row["median_ms"] <= row["p95_ms"]
    assert row["iterations_median"] >= 1
