"""Compute time per control decision of every policy on the same observed states, in one run.

Usage::

    python benchmarks/bench_control.py [--objects 5 10] [--states 8] [--model MODEL] [--task pushing] [--out FILE]

The observed states are frames of scripted roll-outs of the task (``--states`` of them, from
generated trajectories). For every state each policy's controller (default settings:
12 samples, horizon 4, 0.1 s period) decides once, the policies interleaved state by state so a
change of machine load affects all of them alike. ``learned`` needs ``--model`` (from
``energy-margin learn``) and is skipped without it. The table gives the mean and standard
deviation of the wall time per decision and its ratio to the ``task`` policy's; ``--out`` writes
the rows, the machine and its load before and after as JSON.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from functools import partial
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_analysis import machine
from energy_margin.control.commands import command_space
from energy_margin.control.costs import CostContext, CostWeights, get_cost
from energy_margin.control.mppi import Controller, ControllerConfig
from energy_margin.data.dataset import load_dataset
from energy_margin.data.generate import generate_dataset
from energy_margin.runs.versions import engine_versions
from energy_margin.tasks import Trajectory


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="pushing")
    parser.add_argument("--objects", type=int, nargs="+", default=[5, 10])
    parser.add_argument("--states", type=int, default=8)
    parser.add_argument("--model", type=Path, default=None)
    parser.add_argument("--out", type=Path, default=None, help="write the rows here as JSON")
    args = parser.parse_args()
    model = None
    if args.model is not None:
        from energy_margin.learning.margin_model import load_margin_model

        model = load_margin_model(args.model, task_name=args.task)
    policies = ["task", "heuristic", "margin"] + (["learned"] if model is not None else [])
    config = ControllerConfig()
    print(machine())
    load_before = os.getloadavg()[0]
    rows: list[dict[str, object]] = []
    print(f"task {args.task}, {args.states} observed states per row, controller {config.to_dict()}")
    print()
    print("| n_o | policy | ms per decision (mean ± sd) | × task |")
    print("|---|---|---|---|")
    with tempfile.TemporaryDirectory() as scratch:
        for n_objects in args.objects:
            trajectories = max(1, args.states // 4)
            out = Path(scratch) / f"n{n_objects}"
            generate_dataset(args.task, n_objects=n_objects, n_trajectories=trajectories, n_frames=4, seed=0, out=out)
            dataset = load_dataset(out)
            task = dataset.task
            space = command_space(task, n_objects)
            times: dict[str, list[float]] = {policy: [] for policy in policies}
            for index in range(min(args.states, trajectories * 4)):
                t, k = divmod(index, 4)
                frame = dataset.frame(t, k)
                start_time = float(dataset.arrays["frame_time"][t, k])
                trajectory = Trajectory(
                    initial=frame, friction=float(dataset.arrays["friction"][t]), drive=dataset.arrays["drive"][t]
                )
                held = None if space.initial_targets(trajectory) is None else np.asarray(frame.robot_q, dtype=float)
                drive_of = partial(space.analysis_drive, trajectory)
                for policy in policies:
                    context = CostContext(
                        task,
                        length_scale=space.length_scale,
                        weights=CostWeights(),
                        friction=trajectory.friction,
                        drive=trajectory.drive,
                        analysis_drive=drive_of,
                        margin_expansions=config.margin_expansions,
                        margin_samples=config.margin_samples,
                        seed_sequence=np.random.SeedSequence(index),
                        model=model,
                    )
                    controller = Controller(
                        task, space, trajectory, get_cost(policy), context, config, np.random.default_rng(index)
                    )
                    started = time.perf_counter()
                    controller.decide(frame, start_time, held)
                    times[policy].append(time.perf_counter() - started)
            base = statistics.mean(times["task"])
            for policy in policies:
                values = times[policy]
                mean, spread = statistics.mean(values), statistics.stdev(values) if len(values) > 1 else 0.0
                print(f"| {n_objects} | {policy} | {1000 * mean:.0f} ± {1000 * spread:.0f} | {mean / base:.2f} |")
                rows.append({"n_objects": n_objects, "policy": policy, "ms": 1000 * mean, "ms_sd": 1000 * spread,
                             "ratio": mean / base, "states": len(values)})  # fmt: skip
    if args.out is not None:
        document = {
            "command": f"python benchmarks/bench_control.py --states {args.states}"
            + (" --model MODEL" if args.model else "") + " --out FILE",
            "machine": machine(), "versions": engine_versions(), "task": args.task,
            "model": None if args.model is None else args.model.name, "controller": config.to_dict(),
            "load_before": load_before, "load_after": os.getloadavg()[0], "rows": rows,
        }  # fmt: skip
        args.out.write_text(json.dumps(document, indent=2) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
