"""Live-scoring latency: expansions reached and scores within a wall-clock budget, beside the full analysis.

Usage::

    python benchmarks/bench_live.py DIR [--frames 30] [--budgets 0.02 0.05 0.1] [--model MODEL] [--seed 0]
        [--json]

DIR is an analysed dataset (``scores.csv`` from ``analyze`` with its default 300 expansions). For
a random sample of its frames (``--seed``) this script, in one process, one frame after another:

* re-runs the frame's full analysis (``analyze_frame``, the frame's seed from ``scores.csv``) and
  times it;
* calls ``score_state`` with every budget (reusing one simulator per frame, built beforehand and
  timed apart) with the same seed, so the budgeted tree is the first expansions of the full one;
* with ``--model``, times ``MarginModel.score_state`` on the same state and one batched
  ``MarginModel.predict`` over the sample.

It prints, per budget, the expansions reached (median, range), the seconds used (median, max) and
the mean absolute difference of both scores to the full analysis.
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

from energy_margin.analysis.frame import AnalyzerConfig, analyze_frame
from energy_margin.analysis.live import score_state
from energy_margin.data.dataset import load_dataset
from energy_margin.data.scores_file import load_scores
from energy_margin.learning.margin_model import load_margin_model


def measure(args: argparse.Namespace) -> dict[str, Any]:
    dataset = load_dataset(args.dataset)
    scores = load_scores(args.dataset)
    analysis = json.loads((dataset.path / "analysis.json").read_text()) if dataset.path else {}
    config = AnalyzerConfig(**analysis["analyzer"]) if "analyzer" in analysis else AnalyzerConfig()
    task = dataset.task
    rng = np.random.default_rng(args.seed)
    rows = rng.choice(len(scores["trajectory"]), size=min(args.frames, len(scores["trajectory"])), replace=False)
    model = load_margin_model(args.model, task_name=task.name) if args.model else None
    full_s, build_s, learned_s = [], [], []
    live: dict[float, list[tuple[int, float, float, float]]] = {budget: [] for budget in args.budgets}
    states = []
    for row in rows:
        trajectory, index = int(scores["trajectory"][row]), int(scores["frame"][row])
        seed = int(scores["seed"][row])
        state = dataset.frame(trajectory, index)
        states.append(state)
        friction = float(dataset.arrays["friction"][trajectory])
        drive = dataset.arrays["drive"][trajectory]
        start_time = float(dataset.arrays["frame_time"][trajectory, index])
        tick = time.perf_counter()
        simulator = task.make_simulator(dataset.n_objects, friction, drive, config.engine)
        build_s.append(time.perf_counter() - tick)
        full, _ = analyze_frame(
            task,
            state,
            friction=friction,
            drive=drive,
            seed=seed,
            config=config,
            start_time=start_time,
            simulator=simulator,
        )
        full_s.append(full.runtime_s)
        for budget in args.budgets:
            result = score_state(
                task,
                state,
                friction=friction,
                drive=drive,
                budget_s=budget,
                seed=seed,
                start_time=start_time,
                simulator=simulator,
                config=config,
            )
            live[budget].append(
                (
                    result.expansions,
                    result.seconds,
                    abs(result.capture - full.capture_score),
                    abs(result.success - full.success_score),
                )
            )
        if model is not None:
            model.score_state(task, state)  # warm-up of the feature cache
            learned_s.append(model.score_state(task, state).seconds)
    result: dict[str, Any] = {
        "dataset": str(args.dataset),
        "task": task.name,
        "n_objects": dataset.n_objects,
        "frames": len(rows),
        "full_iterations": config.iterations,
        "full_seconds_median": statistics.median(full_s),
        "full_seconds_mean": statistics.fmean(full_s),
        "simulator_build_seconds_median": statistics.median(build_s),
        "budgets": {},
        "machine": f"{platform.machine()}, {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f}",
    }
    for budget, values in live.items():
        expansions = [v[0] for v in values]
        seconds = [v[1] for v in values]
        result["budgets"][str(budget)] = {
            "expansions_median": statistics.median(expansions),
            "expansions_min": min(expansions),
            "expansions_max": max(expansions),
            "seconds_median": statistics.median(seconds),
            "seconds_max": max(seconds),
            "capture_abs_diff_mean": statistics.fmean(v[2] for v in values),
            "success_abs_diff_mean": statistics.fmean(v[3] for v in values),
        }
    if model is not None:
        tick = time.perf_counter()
        model.predict(task, states)
        batched = time.perf_counter() - tick
        result["learned"] = {
            "kind": model.kind,
            "single_seconds_median": statistics.median(learned_s),
            "batched_seconds_per_frame": batched / len(states),
        }
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("dataset")
    parser.add_argument("--frames", type=int, default=30)
    parser.add_argument("--budgets", type=float, nargs="+", default=[0.02, 0.05, 0.1])
    parser.add_argument("--model", default=None)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    result = measure(args)
    if args.json:
        print(json.dumps(result, sort_keys=True))
        return
    print(
        f"{result['task']} n_o={result['n_objects']}, {result['frames']} frames; {result['machine']}\n"
        f"full analysis ({result['full_iterations']} expansions): median {result['full_seconds_median']:.3f} s "
        f"(mean {result['full_seconds_mean']:.3f} s); simulator build {result['simulator_build_seconds_median']:.4f} s"
    )
    print("budget_s  expansions (median, min-max)  seconds (median, max)  |Δcapture|  |Δsuccess|")
    for budget, row in result["budgets"].items():
        print(
            f"{float(budget):8.3f}  {row['expansions_median']:10.1f} ({row['expansions_min']}-{row['expansions_max']})"
            f"        {row['seconds_median']:.4f}, {row['seconds_max']:.4f}        "
            f"{row['capture_abs_diff_mean']:.3f}       {row['success_abs_diff_mean']:.3f}"
        )
    if "learned" in result:
        learned = result["learned"]
        print(
            f"learned ({learned['kind']}): {learned['single_seconds_median'] * 1e6:.0f} µs for one state, "
            f"{learned['batched_seconds_per_frame'] * 1e6:.0f} µs per frame batched"
        )


if __name__ == "__main__":
    main()
