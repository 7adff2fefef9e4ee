"""benchmarks/bench_live.py: its results file, budgets and caps as rows, on a tiny analysed set."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from bench_modules import load_benchmark
from energy_margin.cli import main


def test_budgets_and_caps_are_rows_of_the_results_file(tmp_path: Path) -> None:
    bench = load_benchmark("bench_live")
    data = tmp_path / "push"
    generate = ["generate", "--task", "pushing", "--objects", "3", "--trajectories", "2", "--frames", "2"]
    assert main([*generate, "--seed", "5", "--out", str(data)]) == 0
    assert main(["analyze", str(data), "--expansions", "12", "--continuation", "0", "--no-progress"]) == 0
    args = argparse.Namespace(dataset=str(data), frames=3, budgets=[0.005], expansions=[4, 12], model=None, seed=0)
    result = bench.measure(args)
    assert result["frames"] == 3 and result["full_expansions"] == 12
    [budget] = result["budgets"]
    assert budget["budget_s"] == 0.005 and 1 <= budget["expansions_min"] <= budget["expansions_max"] < 2000
    caps = result["expansions"]
    assert [row["expansions"] for row in caps] == [4, 12]
    # At the full analysis' own budget the capped call grows the same tree: the same scores.
    assert caps[1]["capture_abs_diff_mean"] == 0.0 and caps[1]["success_abs_diff_mean"] == 0.0
    assert caps[1]["capture_agree_at_half"] == 1.0
    json.dumps(result)  # a results file holds it as it is
