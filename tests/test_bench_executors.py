"""benchmarks/bench_executors.py: real analyses per executor, the same scores with 1 and 2 workers, memory rows."""

from __future__ import annotations

import argparse
from pathlib import Path

from bench_modules import load_benchmark


def test_executor_rows_agree_on_scores_and_memory_rows_follow_the_frames(tmp_path: Path) -> None:
    bench = load_benchmark("bench_executors")
    args = argparse.Namespace(
        objects=2, trajectories=2, frames=2, expansions=3, ray=False, memory_frames=3, memory_objects=2,
        memory_iterations=3,
    )  # fmt: skip
    rows = bench.time_executors(args, tmp_path)
    assert [(row["executor"], row["workers"]) for row in rows] == [("local", 1), ("local (same scores)", 2)]
    assert all(row["wall_s"] > 0 and row["frames_per_s"] > 0 for row in rows)
    memory = bench.track_memory(args, tmp_path)
    assert [row["frames"] for row in memory] == [0, 3]
    assert all(row["resident_mib"] > 0 for row in memory)
