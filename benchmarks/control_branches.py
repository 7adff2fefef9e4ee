"""Can the controller's sampled commands change an episode's outcome, and does its cost rank them?

Usage::

    python benchmarks/control_branches.py --task scooping --objects 5 --episodes 40 \\
        --times 0.3,0.5,0.7,0.9,1.1,1.3,1.5,1.7 --scores task margin learned --model scoop.npz \\
        [--lookahead 0 10 20] [--disturbance hard] [--seed 0] [--json OUT.json]

For every look-ahead it runs :func:`energy_margin.control.branches.branch_study` (the same
episodes, decision states and sampled sequences each time: only the scores' predictions change)
and prints the nominal success rate, how many decision states split (some sampled sequences
succeed on the plant, others fail), how many failing episodes one sampled sequence rescues, and
each score's concordance (P(a succeeding sequence scores above a failing one) at split states;
0.5 is a coin) overall and per decision time.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_analysis import machine
from energy_margin.control.branches import SCORES, branch_study
from energy_margin.control.disturbances import get_disturbance
from energy_margin.control.mppi import ControllerConfig
from energy_margin.tasks import get_task


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="scooping")
    parser.add_argument("--objects", type=int, default=5)
    parser.add_argument("--episodes", type=int, default=40)
    parser.add_argument("--times", default="0.3,0.5,0.7,0.9,1.1,1.3,1.5,1.7", help="decision times, s")
    parser.add_argument("--scores", nargs="+", default=["task", "margin"], choices=SCORES)
    parser.add_argument("--model", type=Path, default=None, help="learned margin, for the learned score")
    parser.add_argument("--lookahead", type=int, nargs="+", default=[0])
    parser.add_argument("--disturbance", default="hard")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", type=Path, default=None, help="write every study's summary here")
    args = parser.parse_args()
    model = None
    if args.model is not None:
        from energy_margin.learning.margin_model import load_margin_model

        model = load_margin_model(args.model, task_name=args.task)
    task = get_task(args.task)
    times = [float(value) for value in args.times.split(",")]
    print(machine())
    summaries = {}
    for lookahead in args.lookahead:
        config = ControllerConfig(lookahead=lookahead)
        started = time.perf_counter()
        study = branch_study(
            task,
            n_objects=args.objects,
            episodes=args.episodes,
            disturbance=get_disturbance(args.disturbance),
            seed=args.seed,
            decision_times=times,
            config=config,
            scores=args.scores,
            model=model,
        )
        summary = study.summary()
        summaries[str(lookahead)] = summary
        print()
        print(
            f"{args.task}, {args.objects} objects, {args.disturbance}, seed {args.seed}, "
            f"{summary['episodes']} episodes, "
            f"K = {config.samples}, H = {config.horizon}, look-ahead {lookahead} periods "
            f"({time.perf_counter() - started:.0f} s)"
        )
        print(
            f"nominal success {summary['nominal_success_rate']:.3f}; split states {summary['split_states']} of "
            f"{summary['states']}; failures rescued by one sampled sequence {summary['rescuable_failures']} of "
            f"{summary['failures']}"
        )
        names = [name for name in SCORES if name in args.scores]
        print()
        print("| decision time (s) | split states | " + " | ".join(f"concordance `{name}`" for name in names) + " |")
        print("|---|---|" + "---|" * len(names))
        for row in summary["per_time"]:
            cells = " | ".join(f"{row[f'concordance_{name}']:.2f}" for name in names)
            print(f"| {row['time']:.1f} | {row['split']} of {row['states']} | {cells} |")
        cells = " | ".join(f"**{summary[f'concordance_{name}']:.2f}**" for name in names)
        print(f"| all | {summary['split_states']} of {summary['states']} | {cells} |")
    if args.json is not None:
        args.json.write_text(json.dumps(summaries, indent=1))


if __name__ == "__main__":
    main()
