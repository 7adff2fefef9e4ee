"""benchmarks/engine_scooping.py: which boxes count as lifted."""

from __future__ import annotations

import numpy as np
import pytest

from bench_modules import load_benchmark


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("engine_scooping")


def test_a_box_is_lifted_from_the_success_height_above_resting(bench) -> None:
    heights = np.array([0.01, 0.059, 0.061, 0.09])
    found = bench.lifted(heights, resting=0.01, success_height=0.05)
    assert found.tolist() == [False, False, True, True]


def test_the_task_defines_what_the_benchmark_reads(bench) -> None:
    from energy_margin.tasks import get_task

    config = get_task("scooping").config
    assert config.success_height > 0.0
    assert config.box_half_edge > 0.0
    assert hasattr(config, "table_top")
