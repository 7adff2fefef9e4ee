"""``energy-margin sweep``: a design sweep: success rate and energy margins per task design."""

from __future__ import annotations

import argparse
import os
import sys

from energy_margin.cli.common import (
    add_engine,
    add_old_spelling,
    add_seed,
    add_set,
    analyzer_default,
    positive_int,
    task_overrides,
)
from energy_margin.errors import EnergyMarginError
from energy_margin.planning.costs import COST_MODELS
from energy_margin.planning.methods import METHODS
from energy_margin.tasks import available_tasks

__all__ = [
    "EXAMPLES",
    "NAME",
    "PARAMETER_FLAGS",
    "SUMMARY",
    "add_arguments",
    "run",
]

NAME = "sweep"
SUMMARY = "design sweep: success rate and energy margins per task design, and how well the margin ranks them"
EXAMPLES = (
    "energy-margin sweep --task scooping --param scoop_angle=1.1,1.2,1.31 --param open_gap=0.07,0.09 "
    "--trajectories 20 --frames 10 --objects 5 --seed 0 --out runs/sweep-scoop --workers 2",
    "energy-margin sweep --task pushing --param pusher_width=0.4,0.6,0.8 --trajectories 20 --objects 5 "
    "--seed 0 --out runs/sweep-push",
    "energy-margin sweep --task scooping --param finger_stiffness=100,400,2000 --trajectories 20 --objects 5 "
    "--out runs/sweep-stiffness",
)
#: Keyword arguments of :func:`~energy_margin.design.sweep.design_sweep` named otherwise here.
PARAMETER_FLAGS = {
    "n_trajectories": "--trajectories",
    "n_frames": "--frames",
    "n_objects": "--objects",
    "trajectory_counts": "--counts",
    "params": "--param",
    "fixed": "--set",
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``sweep``."""
    tasks = available_tasks()
    parser.add_argument("--task", required=True, choices=tasks, help=f"registered task: {', '.join(tasks)}")
    parser.add_argument(
        "--param",
        action="append",
        required=True,
        metavar="NAME=V1,V2,...",
        help="a swept setting and its values (repeat for a grid: the Cartesian product); a task setting "
        "or an alias: scooping finger_stiffness (N/m, one stiffness per design), pushing pusher_width (m)",
    )
    parser.add_argument("--trajectories", type=positive_int, required=True, help="trajectories per design (>= 2)")
    parser.add_argument("--frames", type=positive_int, default=10, help="frames per trajectory (default 10)")
    parser.add_argument("--objects", type=positive_int, help="objects per scene")
    add_seed(parser)
    parser.add_argument("--out", required=True, help="sweep directory (a rerun resumes it)")
    parser.add_argument(
        "--overwrite",
        action="store_true",
        help="replace a sweep of other settings in --out (its sweep.json, designs/ and results only)",
    )
    parser.add_argument("--workers", type=positive_int, default=1, help="analysis worker processes (default 1)")
    add_engine(parser, records=True)  # the sweep generates its sets on it, then analyses them
    add_set(parser, "a task setting fixed for every design, e.g. --set drive_jitter=0.1")
    expansions = analyzer_default("expansions")
    add_old_spelling(
        parser,
        "--iterations",
        parser.add_argument(
            "--expansions",
            type=positive_int,
            default=expansions,
            help=f"expansions per frame (default {expansions})",
        ),
    )
    parser.add_argument(
        "--method", choices=METHODS, default=analyzer_default("method"), help=f"tree method: {', '.join(METHODS)}"
    )
    parser.add_argument(
        "--cost", choices=tuple(COST_MODELS), default=analyzer_default("cost"), help="incremental cost model"
    )
    parser.add_argument(
        "--batch", type=positive_int, default=analyzer_default("batch"), help="expansions per mujoco.rollout round"
    )
    parser.add_argument(
        "--threads", type=positive_int, default=analyzer_default("threads"), help="mujoco.rollout threads"
    )
    parser.add_argument(
        "--counts",
        type=positive_int,
        nargs="+",
        default=None,
        metavar="T",
        help="trajectory counts t of the convergence table (default 1 2 3 5 10 ... up to --trajectories)",
    )
    parser.add_argument("--bootstrap", type=positive_int, default=2000, help="trajectory resamples of rho's interval")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bars")


def run(args: argparse.Namespace) -> int:
    """Run the sweep and print its table."""
    from energy_margin.analysis.frame import AnalyzerConfig
    from energy_margin.design.params import parse_param
    from energy_margin.design.sweep import RESULTS_FILE, design_sweep, format_table

    params = [parse_param(text) for text in args.param]
    repeated = [name for index, (name, _) in enumerate(params) if name in {n for n, _ in params[:index]}]
    if repeated:
        raise EnergyMarginError(f"--param {repeated[0]} is given twice; list all its values in one --param")
    analyzer = AnalyzerConfig(
        expansions=args.expansions,
        cost=args.cost,
        method=args.method,
        batch=args.batch,
        threads=args.threads,
        engine=args.engine,
    )
    progress = not args.no_progress and (sys.stderr.isatty() or os.environ.get("ENERGY_MARGIN_PROGRESS") == "1")
    results = design_sweep(
        args.task,
        params,
        n_trajectories=args.trajectories,
        n_frames=args.frames,
        n_objects=args.objects,
        seed=args.seed,
        out=args.out,
        workers=args.workers,
        engine=args.engine,
        fixed=task_overrides(args.set),
        analyzer=analyzer,
        trajectory_counts=args.counts,
        bootstrap=args.bootstrap,
        overwrite=args.overwrite,
        progress=progress,
    )
    print(format_table(results))
    print(f"wrote {os.path.join(args.out, RESULTS_FILE)} (JSON and PNG beside it)")
    return 0
