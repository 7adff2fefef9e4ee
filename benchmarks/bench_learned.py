"""Per-query time of a learned margin, one state at a time and batched, beside the tree on the same states.

Usage::

    python benchmarks/bench_learned.py MODEL DIR [DIR ...] [--frames 1000] [--tree-frames 10] [--seed 0] [--json]

MODEL is a margin model (``energy-margin learn``); each DIR an analysed dataset of its task. For
each dataset this script, in one process on one core (numpy's BLAS threads held to 1):

* draws ``--frames`` frames (with replacement when the dataset holds fewer; ``--seed``);
* times ``MarginModel.predict`` on all of them at once (states per second, the median of 5 calls
  after a warm-up) and split into its two parts: the features and the network;
* times ``MarginModel.score_state`` one state at a time on 200 of them (median and 95th percentile);
* re-runs the full tree analysis (``analyze_frame`` with the dataset's analysis settings and each
  frame's seed from ``scores.csv``) of ``--tree-frames`` of them and times it; the speed-ups are
  the tree's median time over the learned times.

CPU times of this process are printed beside the wall times: on a busy machine the wall time
includes waiting for a core, the CPU time does not.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

from energy_margin.analysis.frame import AnalyzerConfig, analyze_frame
from energy_margin.data.dataset import load_dataset
from energy_margin.data.scores_file import load_scores
from energy_margin.learning.margin_model import load_margin_model


def _timed(call: Any, repeats: int) -> tuple[float, float]:
    """Median wall and CPU seconds of ``call()`` over ``repeats`` calls after one warm-up."""
    call()
    wall, cpu = [], []
    for _ in range(repeats):
        tick, cpu_tick = time.perf_counter(), time.process_time()
        call()
        wall.append(time.perf_counter() - tick)
        cpu.append(time.process_time() - cpu_tick)
    return statistics.median(wall), statistics.median(cpu)


def measure_dataset(model: Any, path: str, *, frames: int, tree_frames: int, seed: int) -> dict[str, Any]:
    """The timings of one dataset (see the module docstring)."""
    dataset = load_dataset(path)
    model.check_dataset(dataset)
    task = dataset.task
    rng = np.random.default_rng(seed)
    total = dataset.n_trajectories * dataset.n_frames
    picks = rng.choice(total, size=frames, replace=frames > total)
    states = [dataset.frame(int(p) // dataset.n_frames, int(p) % dataset.n_frames) for p in picks]
    features = model.features(task)
    batched_wall, batched_cpu = _timed(lambda: model.predict(task, states), 5)
    feature_wall, feature_cpu = _timed(lambda: features(states), 5)
    inputs = features(states)
    network_wall, network_cpu = _timed(lambda: model.regressor.predict(inputs), 5)
    single_wall, single_cpu = [], []
    for state in states[:200]:
        tick, cpu_tick = time.perf_counter(), time.process_time()
        model.score_state(task, state)
        single_wall.append(time.perf_counter() - tick)
        single_cpu.append(time.process_time() - cpu_tick)
    scores = load_scores(path)
    analysis = json.loads((dataset.path / "analysis.json").read_text()) if dataset.path else {}
    config = AnalyzerConfig(**analysis["analyzer"]) if isinstance(analysis.get("analyzer"), dict) else AnalyzerConfig()
    tree_wall, tree_cpu = [], []
    for p in picks[:tree_frames]:
        trajectory, index = int(p) // dataset.n_frames, int(p) % dataset.n_frames
        row = int(np.flatnonzero((scores["trajectory"] == trajectory) & (scores["frame"] == index))[0])
        tick, cpu_tick = time.perf_counter(), time.process_time()
        analyze_frame(
            task,
            dataset.frame(trajectory, index),
            friction=float(dataset.arrays["friction"][trajectory]),
            drive=dataset.arrays["drive"][trajectory],
            seed=int(scores["seed"][row]),
            config=config,
            start_time=float(dataset.arrays["frame_time"][trajectory, index]),
        )
        tree_wall.append(time.perf_counter() - tick)
        tree_cpu.append(time.process_time() - cpu_tick)
    tree_s = statistics.median(tree_wall)
    per_state = batched_wall / frames
    single = statistics.median(single_wall)
    return {
        "dataset": str(path),
        "n_objects": dataset.n_objects,
        "frames": frames,
        "batched_s_per_state": per_state,
        "batched_cpu_s_per_state": batched_cpu / frames,
        "states_per_s": 1.0 / per_state,
        "features_s_per_state": feature_wall / frames,
        "network_s_per_state": network_wall / frames,
        "features_cpu_s_per_state": feature_cpu / frames,
        "network_cpu_s_per_state": network_cpu / frames,
        "single_s_median": single,
        "single_s_p95": float(np.quantile(single_wall, 0.95)),
        "single_cpu_s_median": statistics.median(single_cpu),
        "tree_s_median": tree_s,
        "tree_cpu_s_median": statistics.median(tree_cpu),
        "tree_expansions": config.iterations,
        "speedup_single": tree_s / single,
        "speedup_batched": tree_s / per_state,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("model")
    parser.add_argument("datasets", nargs="+")
    parser.add_argument("--frames", type=int, default=1000)
    parser.add_argument("--tree-frames", type=int, default=10)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    model = load_margin_model(args.model)
    with threadpool_limits(limits=1):
        rows = [
            measure_dataset(model, path, frames=args.frames, tree_frames=args.tree_frames, seed=args.seed)
            for path in args.datasets
        ]
    if args.json:
        print(json.dumps({"model": args.model, "kind": model.kind, "rows": rows}, indent=1))
        return
    print(
        f"{model.kind} margin model {args.model}; {platform.processor() or platform.machine()}, "
        f"load average {os.getloadavg()[0]:.1f}; one core (BLAS threads 1)"
    )
    print(
        "| dataset | n_o | batched µs/state (features + network) | states/s | one state µs (median / p95) "
        "| tree s/frame | speed-up one / batched |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|")
    for row in rows:
        print(
            f"| {row['dataset']} | {row['n_objects']} | {row['batched_s_per_state'] * 1e6:.1f} "
            f"({row['features_s_per_state'] * 1e6:.1f} + {row['network_s_per_state'] * 1e6:.1f}) "
            f"| {row['states_per_s']:,.0f} | {row['single_s_median'] * 1e6:.0f} / {row['single_s_p95'] * 1e6:.0f} "
            f"| {row['tree_s_median']:.3f} | {row['speedup_single']:,.0f}× / {row['speedup_batched']:,.0f}× |"
        )
    print("CPU seconds (this process):")
    for row in rows:
        print(
            f"  {row['dataset']}: batched {row['batched_cpu_s_per_state'] * 1e6:.1f} µs/state "
            f"(features {row['features_cpu_s_per_state'] * 1e6:.1f}, "
            f"network {row['network_cpu_s_per_state'] * 1e6:.1f}), "
            f"one state {row['single_cpu_s_median'] * 1e6:.0f} µs, tree {row['tree_cpu_s_median']:.3f} s"
        )


if __name__ == "__main__":
    main()
