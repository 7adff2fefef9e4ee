"""benchmarks/batched_converge.py: a replayed rule stops where analyze --converge stops a batched tree."""

from __future__ import annotations

from pathlib import Path

import pytest

from bench_modules import load_benchmark
from energy_margin.analysis.frame import analyze_frame
from energy_margin.data.dataset import load_dataset


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("batched_converge")


def test_replay_honours_the_whole_budget_and_the_first_stop(bench) -> None:
    flat = [(32 * (i + 1), 0.9, 0.2) for i in range(9)] + [(300, 0.9, 0.2)]
    assert bench.replay(flat, None) == len(flat) - 1
    # Flat scores: the projected rule stops at the first check that looks 50 expansions back (96).
    assert flat[bench.replay(flat, bench.RULES["projected 0.02"])][0] == 96
    assert flat[bench.replay(flat, bench.RULES["projected 0.02, no stop before 192"])][0] == 192
    # The success score never left 0: projected-reached never stops.
    unreached = [(n, c, 0.0) for n, c, _ in flat]
    assert bench.replay(unreached, bench.RULES["projected-reached 0.02"]) == len(flat) - 1


def test_a_replayed_trace_is_analyze_with_the_adaptive_budget(bench, tiny_dataset: Path) -> None:
    bench._init(str(tiny_dataset))
    dataset = load_dataset(tiny_dataset)
    trajectory, frame, rows = bench._trace((1, 1, 7, 32))
    assert (trajectory, frame) == (1, 1)
    assert [row[0] for row in rows] == [32 * (i + 1) for i in range(9)] + [300]
    direct, _ = analyze_frame(
        dataset.task,
        dataset.frame(1, 1),
        friction=float(dataset.arrays["friction"][1]),
        drive=dataset.arrays["drive"][1],
        seed=7,
        config=bench._config(32, converge=0.02),
        start_time=float(dataset.arrays["frame_time"][1, 1]),
    )
    assert rows[bench.replay(rows, bench.RULES["projected 0.02"])] == (
        direct.expansions,
        direct.capture_score,
        direct.success_score,
    )
