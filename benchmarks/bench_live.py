"""Live-scoring latency: expansions reached and scores within a wall-clock budget, beside the full analysis.

Usage::

    python benchmarks/bench_live.py DIR [--frames 30] [--budgets 0.02 0.05 0.1] [--expansions 10 25 50 100]
        [--model MODEL] [--seed 0] [--json] [--out FILE]

DIR is an analysed dataset (``scores.csv`` from ``analyze`` with its default 300 expansions). For
a random sample of its frames (``--seed``) this script, in one process, one frame after another:

* re-runs the frame's full analysis (``analyze_frame``, the frame's seed from ``scores.csv``) and
  times it;
* calls ``score_state`` with every budget (reusing one simulator per frame, built beforehand and
  timed apart) with the same seed, so the budgeted tree is the first expansions of the full one;
* calls ``score_state`` without a deadline at every cap of ``--expansions`` (deterministic; its
  CPU time does not depend on the machine's load, so budget / CPU per call tells what a budget
  reaches on an idle core);
* with ``--model``, times ``MarginModel.score_state`` on the same state and one batched
  ``MarginModel.predict`` over the sample.

It prints, per budget, the expansions reached (median, range), the seconds used (median, max) and
the mean absolute difference of both scores to the full analysis (and how often both sides of 0.5
agree); per cap, the same with the CPU seconds per call. ``--out`` writes the results (JSON) to a file.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.analysis.frame import AnalyzerConfig, analyze_frame
from energy_margin.analysis.live import score_state
from energy_margin.data.dataset import load_dataset
from energy_margin.data.scores_file import load_scores
from energy_margin.learning.margin_model import load_margin_model

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_analysis import machine  # the machine line of the other benchmarks


def measure(args: argparse.Namespace) -> dict[str, Any]:
    load_before = os.getloadavg()[0]
    dataset = load_dataset(args.dataset)
    scores = load_scores(args.dataset)
    analysis = json.loads((dataset.path / "analysis.json").read_text()) if dataset.path else {}
    config = AnalyzerConfig(**analysis["analyzer"]) if "analyzer" in analysis else AnalyzerConfig()
    task = dataset.task
    rng = np.random.default_rng(args.seed)
    rows = rng.choice(len(scores["trajectory"]), size=min(args.frames, len(scores["trajectory"])), replace=False)
    model = load_margin_model(args.model, task_name=task.name) if args.model else None
    full_s, full_cpu_s, build_s, learned_s, learned_cpu_s = [], [], [], [], []
    live: dict[float, list[tuple[int, float, float, float]]] = {budget: [] for budget in args.budgets}
    capped: dict[int, list[tuple[float, float, float, float, bool, bool]]] = {cap: [] for cap in args.expansions}
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
        cpu_tick = time.process_time()
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
        full_cpu_s.append(time.process_time() - cpu_tick)
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
        for cap in args.expansions:
            cpu_tick = time.process_time()
            result = score_state(
                task,
                state,
                friction=friction,
                drive=drive,
                budget_s=None,
                max_expansions=cap,
                seed=seed,
                start_time=start_time,
                simulator=simulator,
                config=config,
            )
            capped[cap].append(
                (
                    result.seconds,
                    time.process_time() - cpu_tick,
                    abs(result.capture - full.capture_score),
                    abs(result.success - full.success_score),
                    (result.capture >= 0.5) == (full.capture_score >= 0.5),
                    (result.success >= 0.5) == (full.success_score >= 0.5),
                )
            )
        if model is not None:
            model.score_state(task, state)  # warm-up of the feature cache
            cpu_tick = time.process_time()
            learned_s.append(model.score_state(task, state).seconds)
            learned_cpu_s.append(time.process_time() - cpu_tick)
    result: dict[str, Any] = {
        "dataset": str(args.dataset),
        "task": task.name,
        "n_objects": dataset.n_objects,
        "frames": len(rows),
        "full_expansions": config.expansions,
        "full_seconds_median": statistics.median(full_s),
        "full_seconds_mean": statistics.fmean(full_s),
        "full_cpu_seconds_median": statistics.median(full_cpu_s),
        "simulator_build_seconds_median": statistics.median(build_s),
        "budgets": [],
        "machine": machine(),
        "load_before": load_before,
        "load_after": os.getloadavg()[0],
    }
    for budget, values in live.items():
        expansions = [v[0] for v in values]
        seconds = [v[1] for v in values]
        result["budgets"].append({
            "budget_s": budget,
            "expansions_median": statistics.median(expansions),
            "expansions_min": min(expansions),
            "expansions_max": max(expansions),
            "seconds_median": statistics.median(seconds),
            "seconds_max": max(seconds),
            "capture_abs_diff_mean": statistics.fmean(v[2] for v in values),
            "success_abs_diff_mean": statistics.fmean(v[3] for v in values),
        })  # fmt: skip
    result["expansions"] = [
        {
            "expansions": cap,
            "seconds_median": statistics.median(v[0] for v in values),
            "cpu_seconds_median": statistics.median(v[1] for v in values),
            "capture_abs_diff_mean": statistics.fmean(v[2] for v in values),
            "success_abs_diff_mean": statistics.fmean(v[3] for v in values),
            "capture_agree_at_half": statistics.fmean(float(v[4]) for v in values),
            "success_agree_at_half": statistics.fmean(float(v[5]) for v in values),
        }
        for cap, values in capped.items()
    ]
    if model is not None:
        tick = time.perf_counter()
        model.predict(task, states)
        batched = time.perf_counter() - tick
        result["learned"] = {
            "kind": model.kind,
            "single_seconds_median": statistics.median(learned_s),
            "single_cpu_seconds_median": statistics.median(learned_cpu_s),
            "speedup_cpu": statistics.median(full_cpu_s) / max(statistics.median(learned_cpu_s), 1e-9),
            "batched_seconds_per_frame": batched / len(states),
        }
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("dataset")
    parser.add_argument("--frames", type=int, default=30)
    parser.add_argument("--budgets", type=float, nargs="+", default=[0.02, 0.05, 0.1])
    parser.add_argument("--expansions", type=int, nargs="+", default=[10, 25, 50, 100])
    parser.add_argument("--model", default=None)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--out", type=Path, help="results file (JSON)")
    args = parser.parse_args()
    result = measure(args)
    if args.out:
        args.out.write_text(json.dumps(result, indent=2, sort_keys=True) + "\n")
    if args.json:
        print(json.dumps(result, sort_keys=True))
        return
    print(
        f"{result['task']} n_o={result['n_objects']}, {result['frames']} frames; {result['machine']}\n"
        f"full analysis ({result['full_expansions']} expansions): median {result['full_seconds_median']:.3f} s "
        f"(mean {result['full_seconds_mean']:.3f} s, CPU median {result['full_cpu_seconds_median']:.3f} s); "
        f"simulator build {result['simulator_build_seconds_median']:.4f} s"
    )
    print("budget_s  expansions (median, min-max)  seconds (median, max)  |Δcapture|  |Δsuccess|")
    for row in result["budgets"]:
        print(
            f"{row['budget_s']:8.3f}  {row['expansions_median']:10.1f} "
            f"({row['expansions_min']}-{row['expansions_max']})        "
            f"{row['seconds_median']:.4f}, {row['seconds_max']:.4f}        "
            f"{row['capture_abs_diff_mean']:.3f}       {row['success_abs_diff_mean']:.3f}"
        )
    print("cap  seconds (median)  CPU s (median)  |Δcapture|  |Δsuccess|  agree@0.5 capture, success")
    for row in result["expansions"]:
        print(
            f"{row['expansions']:3d}  {row['seconds_median']:16.4f}  {row['cpu_seconds_median']:14.4f}  "
            f"{row['capture_abs_diff_mean']:10.3f}  {row['success_abs_diff_mean']:10.3f}  "
            f"{row['capture_agree_at_half']:.2f}, {row['success_agree_at_half']:.2f}"
        )
    if "learned" in result:
        learned = result["learned"]
        print(
            f"learned ({learned['kind']}): {learned['single_seconds_median'] * 1e6:.0f} µs for one state "
            f"(CPU {learned['single_cpu_seconds_median'] * 1e6:.0f} µs, {learned['speedup_cpu']:.0f}x less CPU than "
            f"the full analysis), {learned['batched_seconds_per_frame'] * 1e6:.0f} µs per frame batched"
        )


if __name__ == "__main__":
    main()
