"""benchmarks/time_tests.py: the counts it reads from pytest's closing line."""

from __future__ import annotations

import pytest

from bench_modules import load_benchmark


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("time_tests")


def test_every_count_of_the_closing_line_is_read(bench) -> None:
    line = "===== 1 failed, 2019 passed, 5 skipped, 10 warnings, 2 errors in 481.73s (0:08:01) ====="
    assert bench.counts(line) == {"failed": 1, "passed": 2019, "skipped": 5, "error": 2}


def test_a_line_without_counts_reads_as_none(bench) -> None:
    assert bench.counts("no tests ran in 0.01s") == {}
