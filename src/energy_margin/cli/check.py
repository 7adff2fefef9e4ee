"""``energy-margin check``: list every problem of a dataset and of its scores."""

from __future__ import annotations

import argparse

from energy_margin.errors import EnergyMarginError

__all__ = [
    "EXAMPLES",
    "NAME",
    "SUMMARY",
    "add_arguments",
    "run",
]

NAME = "check"
SUMMARY = "list every problem of a dataset (and of its scores), one per line"
EXAMPLES = ("energy-margin check runs/push10", "energy-margin check runs/push10 --no-overlaps")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``check``."""
    parser.add_argument("dataset", help="dataset directory")
    parser.add_argument("--no-overlaps", action="store_true", help="skip the (simulated) overlap check")


def run(args: argparse.Namespace) -> int:
    """Print warnings and problems; fail when there is a problem."""
    from energy_margin.data.validation import check_dataset

    warnings: list = []
    problems = check_dataset(args.dataset, overlaps=not args.no_overlaps, scores=None, warnings=warnings)
    for warning in warnings:
        print(f"warning: {warning}")
    for problem in problems:
        # A problem of the directory itself names no file: say which directory.
        print(problem if problem.file else f"{args.dataset}: {problem}")
    if problems:
        raise EnergyMarginError(f"{len(problems)} problem(s) in {args.dataset}")
    print(f"{args.dataset}: ok")
    return 0
