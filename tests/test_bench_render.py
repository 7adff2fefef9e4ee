"""benchmarks/bench_render.py: the results file it writes with ``--json``."""

from __future__ import annotations

import json

import pytest

from bench_modules import load_benchmark


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("bench_render")


def test_the_results_file_keeps_the_rows_by_task_with_the_versions(bench) -> None:
    rows = {"pushing": {"task": "pushing", "picture_s": 0.05}, "scooping": {"task": "scooping", "picture_s": 0.03}}
    written = bench.results_file(rows, 10)
    assert written["tasks"] == rows
    assert written["repeats"] == 10
    assert "mujoco" in written["versions"]
    assert written["machine"]
    json.dumps(written)
