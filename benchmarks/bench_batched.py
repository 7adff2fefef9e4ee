"""Per-frame time of one-at-a-time against batched (``mujoco.rollout``) expansion, measured in one run.

Usage::

    python benchmarks/bench_batched.py [--objects 10] [--expansions 300] [--batches 8 16 32]
        [--threads 1 2] [--trajectories 2] [--frames 5] [--task pushing] [--out FILE]

Everything runs in this one process. A small dataset is generated in memory; every frame is analysed
with every setting in turn (settings interleaved frame by frame, so a change of machine load hits
them alike). B = 1 is the reference path (one ``mj_setState`` + ``mj_step`` per expansion);
B > 1 propagates B expansions per round through ``mujoco.rollout`` on 1 or more threads. The table
gives the mean per-frame wall time, the part inside the simulator, the speed-up against B = 1 and
the mean capture and success scores (the Monte Carlo and RRT baselines are timed at B = 1 too);
the load average before and after is printed because other processes on the machine change the
multithreaded numbers most. ``--out`` writes the rows, the machine and both load averages as JSON.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import statistics
import sys
from pathlib import Path

import numpy as np

from energy_margin.analysis.frame import AnalyzerConfig, analyze_frame, frame_seeds
from energy_margin.data.dataset import frame_from_arrays
from energy_margin.data.generate import record_trajectory
from energy_margin.sim import make_simulator
from energy_margin.tasks import get_task

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_analysis import machine

Setting = tuple[int, int, str]


def summary_rows(
    settings: list[Setting],
    times: dict[Setting, list[float]],
    physics: dict[Setting, list[float]],
    capture: dict[Setting, list[float]],
    success: dict[Setting, list[float]],
) -> list[dict[str, float | int | str]]:
    """One row per (batch, threads, method) setting: mean time per frame [s] and its spread, physics
    time [s], the speed-up against the EST at B = 1 (the first setting) and the mean scores."""
    reference = statistics.fmean(times[settings[0]])
    rows: list[dict[str, float | int | str]] = []
    for setting in settings:
        mean = statistics.fmean(times[setting])
        rows.append(
            {
                "method": setting[2],
                "batch": setting[0],
                "threads": setting[1],
                "per_frame_s": mean,
                "per_frame_sd": statistics.pstdev(times[setting]),
                "physics_s": statistics.fmean(physics[setting]),
                "speedup": reference / mean,
                "capture_mean": statistics.fmean(capture[setting]),
                "success_mean": statistics.fmean(success[setting]),
            }
        )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="pushing")
    parser.add_argument("--objects", type=int, default=10)
    parser.add_argument("--expansions", type=int, default=300)
    parser.add_argument("--batches", type=int, nargs="+", default=[8, 16, 32])
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--trajectories", type=int, default=2)
    parser.add_argument("--frames", type=int, default=5)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--methods", nargs="*", default=["montecarlo", "rrt"], help="further methods timed at B = 1 (EST always)"
    )
    parser.add_argument("--out", type=Path, help="also write the rows as JSON here")
    args = parser.parse_args()
    task = get_task(args.task)
    settings: list[Setting] = [(1, 1, "est")]
    settings += [(batch, threads, "est") for batch in args.batches for threads in args.threads]
    settings += [(1, 1, method) for method in args.methods]
    configs = {s: AnalyzerConfig(expansions=args.expansions, batch=s[0], threads=s[1], method=s[2]) for s in settings}
    times: dict[Setting, list[float]] = {s: [] for s in settings}
    physics: dict[Setting, list[float]] = {s: [] for s in settings}
    capture: dict[Setting, list[float]] = {s: [] for s in settings}
    success: dict[Setting, list[float]] = {s: [] for s in settings}

    print(f"machine: {machine()}")
    load_before = os.getloadavg()
    print(f"load average before: {' '.join(f'{v:.2f}' for v in load_before)}")
    print(
        f"{args.task}, n_o = {args.objects}, {args.expansions} expansions, "
        f"{args.trajectories} trajectories x {args.frames} frames, one process, settings interleaved"
    )
    seeds = np.random.SeedSequence([args.seed, args.objects]).spawn(args.trajectories)
    for trajectory, child in enumerate(seeds):
        record = record_trajectory(task, args.objects, args.frames, np.random.default_rng(child))
        friction = float(record["friction"])
        simulator = make_simulator(task.build_scene(args.objects, friction, record["drive"]))
        per_frame = frame_seeds(args.seed * 1000 + trajectory, args.frames)
        for k in range(args.frames):
            frame = frame_from_arrays(record, k)
            for setting in settings:
                scores, _ = analyze_frame(
                    task,
                    frame,
                    friction=friction,
                    drive=record["drive"],
                    seed=per_frame[k],
                    config=configs[setting],
                    start_time=float(record["frame_time"][k]),
                    simulator=simulator,
                )
                times[setting].append(scores.runtime_s)
                physics[setting].append(scores.physics_s)
                capture[setting].append(scores.capture_score)
                success[setting].append(scores.success_score)
    load_after = os.getloadavg()
    print(f"load average after: {' '.join(f'{v:.2f}' for v in load_after)}")
    print()
    rows = summary_rows(settings, times, physics, capture, success)
    print("| method | B | threads | per frame [s] | physics [s] | speed-up vs EST B=1 | mean capture | mean success |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for row in rows:
        print(
            f"| {row['method']} | {row['batch']} | {row['threads']} | {row['per_frame_s']:.3f} ± "
            f"{row['per_frame_sd']:.3f} | {row['physics_s']:.3f} | {row['speedup']:.2f}x "
            f"| {row['capture_mean']:.3f} | {row['success_mean']:.3f} |"
        )
    if args.out is not None:
        results = {
            "command": "python benchmarks/bench_batched.py " + " ".join(sys.argv[1:]),
            "date": datetime.date.today().isoformat(),
            "machine": machine(),
            "load_before": round(load_before[0], 2),
            "load_after": round(load_after[0], 2),
            "task": args.task,
            "objects": args.objects,
            "expansions": args.expansions,
            "frames": args.trajectories * args.frames,
            "rows": rows,
        }
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(results, indent=2) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
