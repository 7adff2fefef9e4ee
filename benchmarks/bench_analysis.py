"""Per-frame analysis time against the number of objects, split into physics and planner overhead.

Usage::

    python benchmarks/bench_analysis.py [--task pushing] [--objects 1 3 5 10 20] [--expansions 300]
        [--trajectories 2] [--frames 5] [--cost wrench] [--set timestep=0.0041667]
        [--out docs/figures/bench_analysis.json --label KEY --title NAME]

Everything runs in this one process, one frame after another. For every n_o a small
dataset is generated in memory and each of its frames is analysed; the table reports the mean and
standard deviation of the per-frame wall time, the part spent inside the simulator (restore, step,
read, save), and the rest (node selection, sampling, cost, density bookkeeping, scoring).
``--out`` keeps the rows in a results file under ``--label``, in place of earlier rows of that label
(so one file gathers the rows of several settings, run by run).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from energy_margin.analysis.frame import AnalyzerConfig, analyze_frame, frame_seeds
from energy_margin.cli.common import task_overrides
from energy_margin.data.dataset import frame_from_arrays
from energy_margin.data.generate import record_trajectory
from energy_margin.errors import EnergyMarginError
from energy_margin.sim import make_simulator
from energy_margin.tasks import get_task


def machine() -> str:
    cpu = platform.processor() or "unknown CPU"
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as stream:
            for line in stream:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return (
        f"{cpu}, {os.cpu_count()} logical CPUs, Python {platform.python_version()}, "
        f"MuJoCo {mujoco.__version__}, NumPy {np.__version__}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="pushing", help="registered task (pushing, scooping)")
    parser.add_argument("--objects", type=int, nargs="+", default=[1, 3, 5, 10, 20])
    parser.add_argument("--expansions", type=int, default=300)
    parser.add_argument("--trajectories", type=int, default=2)
    parser.add_argument("--frames", type=int, default=5)
    parser.add_argument("--cost", choices=("wrench", "energy"), default="wrench")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--set", action="append", default=[], metavar="KEY=JSON")
    parser.add_argument("--out", type=Path, help="results file the rows go into (under --label)")
    parser.add_argument("--label", default="default", help="the setting's key in the results file (no spaces)")
    parser.add_argument("--title", help="the setting's name in tables (default: the label)")
    args = parser.parse_args()
    try:
        task = get_task(args.task, task_overrides(args.set))
    except EnergyMarginError as error:
        raise SystemExit(f"bench_analysis.py: {error}") from None
    config = AnalyzerConfig(expansions=args.expansions, cost=args.cost)

    load_before = os.getloadavg()[0]
    print(f"machine: {machine()}; load average {load_before:.2f} before")
    print(
        f"{args.task}, {args.expansions} iterations, cost={args.cost}, timestep={task.config.timestep:.6f} s, "
        f"{args.trajectories} trajectories x {args.frames} frames per n_o, one process"
    )
    rows: list[dict[str, Any]] = []
    print()
    print("| n_o | frames | per frame [s] | physics [s] | overhead [s] | overhead / physics | nodes |")
    print("|---:|---:|---:|---:|---:|---:|---:|")
    for n_objects in args.objects:
        seeds = np.random.SeedSequence([args.seed, n_objects]).spawn(args.trajectories)
        runtimes, physics, nodes = [], [], []
        for trajectory, child in enumerate(seeds):
            record = record_trajectory(task, n_objects, args.frames, np.random.default_rng(child))
            friction = float(record["friction"])
            simulator = make_simulator(task.build_scene(n_objects, friction, record["drive"]))
            per_frame = frame_seeds(args.seed * 1000 + trajectory, args.frames)
            for k in range(args.frames):
                frame = frame_from_arrays(record, k)
                scores, _ = analyze_frame(
                    task,
                    frame,
                    friction=friction,
                    drive=record["drive"],
                    seed=per_frame[k],
                    config=config,
                    start_time=float(record["frame_time"][k]),
                    simulator=simulator,
                )
                runtimes.append(scores.runtime_s)
                physics.append(scores.physics_s)
                nodes.append(scores.nodes)
        mean_runtime = statistics.fmean(runtimes)
        mean_physics = statistics.fmean(physics)
        overhead = mean_runtime - mean_physics
        print(
            f"| {n_objects} | {len(runtimes)} | {mean_runtime:.3f} ± {statistics.pstdev(runtimes):.3f} "
            f"| {mean_physics:.3f} | {overhead:.4f} | {100 * overhead / mean_physics:.1f} % "
            f"| {statistics.fmean(nodes):.0f} |"
        )
        rows.append(
            {
                "label": args.label,
                "title": args.title or args.label,
                "n_objects": n_objects,
                "frames": len(runtimes),
                "per_frame_s": mean_runtime,
                "per_frame_sd": statistics.pstdev(runtimes),
                "physics_s": mean_physics,
                "overhead_s": overhead,
                "overhead_per_physics": overhead / mean_physics,
                "physics_share": mean_physics / mean_runtime,
                "overhead_share": overhead / mean_runtime,
                "nodes": statistics.fmean(nodes),
            }
        )
    if args.out:
        run = {
            "machine": machine(),
            "load_before": load_before,
            "load_after": os.getloadavg()[0],
            "settings": {"task": args.task, "expansions": args.expansions, "cost": args.cost, "set": args.set,
                         "timestep": task.config.timestep, "trajectories": args.trajectories, "frames": args.frames,
                         "seed": args.seed},
        }  # fmt: skip
        write_rows(args.out, args.label, rows, run)
        print(f"wrote {args.out}")


def write_rows(path: Path, label: str, rows: list[dict[str, Any]], run: dict[str, Any]) -> None:
    """Put ``rows`` of setting ``label`` into the results file at ``path``, in place of its earlier rows.

    ``run`` (machine, load, settings) is kept per label under ``runs``.
    """
    kept = json.loads(path.read_text()) if path.exists() else {"rows": [], "runs": {}}
    kept["rows"] = [row for row in kept["rows"] if row["label"] != label] + rows
    kept["runs"][label] = run
    path.write_text(json.dumps(kept, indent=2) + "\n")


if __name__ == "__main__":
    main()
