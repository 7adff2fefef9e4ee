"""``energy-margin study``: the informative questions on 100-trajectory sets, paired intervals, a lambda sweep."""

from __future__ import annotations

import argparse

from energy_margin.cli.common import add_old_spelling, add_seed, non_negative_float, positive_int
from energy_margin.planning.methods import METHODS

__all__ = [
    "EXAMPLES",
    "NAME",
    "SUMMARY",
    "add_arguments",
    "run",
]

NAME = "study"
SUMMARY = "AP with bootstrap and paired intervals per task, method and budget, and AP against lambda (resumable)"
EXAMPLES = (
    "energy-margin study runs/study --workers 2",
    "energy-margin study runs/small --tasks pushing --trajectories 10 --frames 5 --expansions 10 30 --methods est rrt",
    "energy-margin study runs/study --lambdas 0.5 5 50 --lambda-budget 300",
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``study``."""
    from energy_margin.experiments.study import DEFAULT_BUDGETS, TASKS

    parser.add_argument("out", help="output directory (datasets, analyses, study.{csv,json}, figures); resumes")
    parser.add_argument(
        "--tasks",
        nargs="+",
        choices=list(TASKS),
        default=list(TASKS),
        help="tasks (pushing n_o = 10, scooping n_o = 5)",
    )
    parser.add_argument("--trajectories", type=positive_int, default=100, help="trajectories per task (default 100)")
    parser.add_argument("--frames", type=positive_int, default=10, help="frames per trajectory (default 10)")
    add_old_spelling(
        parser,
        "--budgets",
        parser.add_argument(
            "--expansions",
            type=positive_int,
            nargs="+",
            default=list(DEFAULT_BUDGETS),
            help="the budgets to compare: expansions per frame",
        ),
    )
    parser.add_argument(
        "--methods", nargs="+", choices=METHODS, default=list(METHODS), help=f"tree methods: {', '.join(METHODS)}"
    )
    parser.add_argument(
        "--lambdas",
        type=non_negative_float,
        nargs="*",
        default=None,
        help="lambda grid, 1/J, for every task (default: the task's lambda x 10^(k/2), k = -6..6; none: no sweep)",
    )
    parser.add_argument("--lambda-method", choices=METHODS, default="est", help="tree method of the lambda sweep")
    add_old_spelling(
        parser,
        "--lambda-budget",
        parser.add_argument(
            "--lambda-expansions", type=positive_int, default=100, help="expansions per frame of the lambda sweep"
        ),
    )
    parser.add_argument("--workers", type=positive_int, default=1, help="local worker processes")
    add_seed(parser)
    parser.add_argument("--bootstrap", type=positive_int, default=1000, help="trajectory resamples (default 1000)")
    parser.add_argument(
        "--overwrite",
        action="store_true",
        help="replace a study in OUT whose datasets or seed differ for one of --tasks (all of its outputs)",
    )


def run(args: argparse.Namespace) -> int:
    """Run or resume the study (its tables, then its figures) and print its tables."""
    from energy_margin.experiments.study import format_study, run_study

    result = run_study(
        args.out,
        tasks=args.tasks,
        n_trajectories=args.trajectories,
        n_frames=args.frames,
        expansions=args.expansions,
        methods=args.methods,
        lambdas=args.lambdas,
        lambda_method=args.lambda_method,
        lambda_expansions=args.lambda_expansions,
        seed=args.seed,
        workers=args.workers,
        bootstrap=args.bootstrap,
        overwrite=args.overwrite,
    )
    print(format_study(result))
    return 0
