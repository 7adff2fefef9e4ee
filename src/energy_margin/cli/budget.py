"""``energy-margin budget``: AP and runtime against the expansion budget, per tree method."""

from __future__ import annotations

import argparse

from energy_margin.cli.common import add_old_spelling, add_seed, analyzer_default, non_negative_int, positive_int
from energy_margin.planning.methods import METHODS

__all__ = [
    "EXAMPLES",
    "NAME",
    "SUMMARY",
    "add_arguments",
    "run",
]

NAME = "budget"
SUMMARY = "AP (with bootstrap intervals) and runtime against the expansion budget, per tree method"
EXAMPLES = ("energy-margin budget runs/push10 --expansions 10 30 100 300 --methods est montecarlo --workers 2",)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``budget``."""
    parser.add_argument("dataset", help="dataset directory")
    add_old_spelling(
        parser,
        "--budgets",
        parser.add_argument(
            "--expansions",
            type=positive_int,
            nargs="+",
            default=[10, 30, 100, 300, 1000],
            help="the budgets to compare: expansions per frame",
        ),
    )
    parser.add_argument(
        "--methods", nargs="+", choices=METHODS, default=list(METHODS), help=f"tree methods: {', '.join(METHODS)}"
    )
    parser.add_argument("--workers", type=positive_int, default=1, help="local worker processes")
    add_seed(parser)
    parser.add_argument("--bootstrap", type=non_negative_int, default=1000, help="trajectory resamples (default 1000)")
    parser.add_argument("--out", default=None, help="summary CSV (default DIR/budget/budget.csv; JSON, PNG beside)")
    parser.add_argument(
        "--batch", type=positive_int, default=analyzer_default("batch"), help="expansions per mujoco.rollout round"
    )
    parser.add_argument(
        "--threads", type=positive_int, default=analyzer_default("threads"), help="mujoco.rollout threads"
    )
    parser.add_argument(
        "--overwrite",
        action="store_true",
        help="replace a sweep of another dataset, seed or analyzer settings in the work directory",
    )


def run(args: argparse.Namespace) -> int:
    """Run the sweep and print its table."""
    from energy_margin.analysis.frame import AnalyzerConfig
    from energy_margin.experiments.budget import budget_sweep, format_table

    base = AnalyzerConfig(batch=args.batch, threads=args.threads)
    result = budget_sweep(
        args.dataset,
        expansions=args.expansions,
        methods=args.methods,
        workers=args.workers,
        seed=args.seed,
        bootstrap=args.bootstrap,
        out=args.out,
        base=base,
        overwrite=args.overwrite,
    )
    print(format_table(result.rows))
    return 0
