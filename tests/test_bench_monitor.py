"""benchmarks/monitor.py: each scene's sets are made by the command that makes its roll-outs."""

from __future__ import annotations

from pathlib import Path

import pytest

from bench_modules import load_benchmark


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("monitor")


def test_generated_and_controlled_sets_count_their_roll_outs_by_their_command_s_option(bench, tmp_path: Path) -> None:
    out = tmp_path / "set"
    generated = bench.set_command(bench._scene_command("pushing", tmp_path), trajectories=7, frames=4, seed=2, out=out)
    assert generated[:5] == ["generate", "--task", "pushing", "--objects", "10"]
    assert generated[5:] == ["--trajectories", "7", "--frames", "4", "--seed", "2", "--out", str(out), "--overwrite"]
    controlled = bench.set_command(
        bench._scene_command("pushing_control_hard", tmp_path), trajectories=7, frames=4, seed=2, out=out
    )
    assert controlled[0] == "control" and controlled[controlled.index("--disturbance") + 1] == "hard"
    assert controlled[controlled.index("--episodes") + 1] == "7" and "--trajectories" not in controlled
    # The episodes' own analysis is skipped: the benchmark analyses every set alike afterwards.
    assert controlled[controlled.index("--expansions") + 1] == "0"
