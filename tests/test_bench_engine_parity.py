"""benchmarks/engine_parity.py: its agreement measures, and the time step it sets on an import."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bench_modules import load_benchmark


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("engine_parity")


def test_agreement_of_two_analyses(bench) -> None:
    first = np.array([[0.0, 0.2, 0.9], [0.0, 0.6, 1.0]])
    second = np.array([[0.0, 0.3, 0.4], [0.1, 0.7, 1.0]])
    found = bench.agreement(first, second)
    assert found["frames"] == 6
    assert found["zero_in_both"] == 1
    assert found["mean_abs_difference"] == pytest.approx((0 + 0.1 + 0.5 + 0.1 + 0.1 + 0) / 6)
    assert found["max_abs_difference"] == pytest.approx(0.5)
    # 0.9 against 0.4 is the one frame on opposite sides of 0.5.
    assert found["same_side_of_half"] == 5
    assert found["pearson"] == pytest.approx(np.corrcoef(first.ravel(), second.ravel())[0, 1])
    assert found["spearman"] < 1.0
    # Trajectory means 0.367 / 0.533 against 0.233 / 0.6: the same order.
    assert found["trajectory_spearman"] == pytest.approx(1.0)


def test_identical_analyses_agree_fully(bench) -> None:
    scores = np.array([[0.0, 0.25, 0.75], [0.5, 1.0, 0.1]])
    found = bench.agreement(scores, scores.copy())
    assert found["pearson"] == pytest.approx(1.0)
    assert found["spearman"] == pytest.approx(1.0)
    assert found["max_abs_difference"] == 0.0
    assert found["same_side_of_half"] == 6


def test_their_time_step_reaches_the_imported_task(bench, tmp_path: Path) -> None:
    if not bench.REFERENCE_DATA.is_dir():
        pytest.skip(f"the authors' data are not at {bench.REFERENCE_DATA}")
    from energy_margin.data.dataset import load_dataset

    path = bench._imported("pushing", tmp_path / "push", timestep=bench.THEIR_TIMESTEP)
    assert load_dataset(path).task.config.timestep == pytest.approx(1.0 / 240.0)
    plain = bench._imported("pushing", tmp_path / "plain")
    assert load_dataset(plain).task.config.timestep == pytest.approx(1.0 / 120.0)
