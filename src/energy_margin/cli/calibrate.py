"""``energy-margin calibrate``: the likelihood lambda chosen by nested cross-validated AP, by trajectory."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING, Any

from energy_margin.cli.common import (
    add_old_spelling,
    add_seed,
    non_negative_float,
    non_negative_int,
    positive_float,
    positive_int,
    print_json,
)
from energy_margin.errors import EnergyMarginError

if TYPE_CHECKING:
    from energy_margin.evaluation.calibration import Calibration

__all__ = [
    "EXAMPLES",
    "NAME",
    "SUMMARY",
    "add_arguments",
    "format_calibration",
    "run",
]

NAME = "calibrate"
SUMMARY = "choose lambda by cross-validated AP (nested, grouped by trajectory); calibration.json for analyze"
# Then: energy-margin analyze runs/jaco-new --calibration runs/jaco-calibration/calibration.json
EXAMPLES = (
    "energy-margin calibrate runs/jaco --out runs/jaco-calibration --workers 2",
    "energy-margin calibrate runs/jaco --out runs/cal --lambdas 1 5 20 --folds 4 --json",
    "energy-margin calibrate runs/push10 --out runs/push10-cal --objective capture_ap_window2 --expansions 100",
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``calibrate``."""
    from energy_margin.evaluation.calibration import DEFAULT_LAMBDAS, DEFAULT_OBJECTIVE, QUESTIONS

    parser.add_argument("dataset", help="dataset directory (its labels are what the choice is measured on)")
    parser.add_argument("--out", required=True, help="run directory: per-lambda scores and calibration.json")
    parser.add_argument(
        "--lambdas",
        type=non_negative_float,
        nargs="+",
        default=list(DEFAULT_LAMBDAS),
        help=f"lambda grid, 1/J (default {' '.join(f'{x:g}' for x in DEFAULT_LAMBDAS)}; the task's own is added)",
    )
    parser.add_argument("--folds", type=positive_int, default=5, help="K folds of trajectories, >= 2 (default 5)")
    parser.add_argument(
        "--objective",
        nargs="+",
        choices=QUESTIONS,
        default=list(DEFAULT_OBJECTIVE),
        help=f"questions whose mean AP the choice maximises (default {' '.join(DEFAULT_OBJECTIVE)})",
    )
    parser.add_argument(
        "--grow",
        action="store_true",
        help="also choose the settings that change the trees: wrench-bound and propagation-length factors "
        "(default grids 0.5 1 2 each; every pair grows its own trees)",
    )
    parser.add_argument(
        "--wrench-scales", type=positive_float, nargs="+", default=None, help="wrench-bound factors (implies --grow)"
    )
    parser.add_argument(
        "--duration-scales",
        type=positive_float,
        nargs="+",
        default=None,
        help="propagation-length factors (implies --grow)",
    )
    add_old_spelling(
        parser,
        "--iterations",
        parser.add_argument(
            "--expansions",
            type=positive_int,
            default=300,
            help="expansions per frame (default 300)",
        ),
    )
    parser.add_argument(
        "--continuation",
        type=non_negative_int,
        default=0,
        metavar="K",
        help="score success by K continuations of the script, drawn again at every lambda, as "
        "analyze --continuation K does (default 0: the tree's own success score)",
    )
    parser.add_argument("--workers", type=positive_int, default=1, help="worker processes (default 1)")
    parser.add_argument("--resamples", type=positive_int, default=1000, help="bootstrap resamples (default 1000)")
    add_seed(parser)
    parser.add_argument("--overwrite", action="store_true", help="replace a calibration of other settings in --out")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    parser.add_argument("--json", action="store_true", help="print the result as one JSON object")


def run(args: argparse.Namespace) -> int:
    """Grow the trees once, choose lambda fold by fold, print the table."""
    from energy_margin.analysis.frame import AnalyzerConfig
    from energy_margin.evaluation.calibration import calibrate

    if args.folds < 2:
        raise EnergyMarginError(f"--folds must be >= 2, got {args.folds}")
    grow = args.grow or args.wrench_scales is not None or args.duration_scales is not None
    default_scales = (0.5, 1.0, 2.0) if grow else (1.0,)
    wrench_scales = tuple(args.wrench_scales) if args.wrench_scales is not None else default_scales
    duration_scales = tuple(args.duration_scales) if args.duration_scales is not None else default_scales
    result = calibrate(
        args.dataset,
        args.out,
        lambdas=tuple(args.lambdas),
        folds=args.folds,
        objective=tuple(args.objective),
        config=AnalyzerConfig(expansions=args.expansions, continuation=args.continuation),
        seed=args.seed,
        workers=args.workers,
        resamples=args.resamples,
        wrench_scales=wrench_scales,
        duration_scales=duration_scales,
        progress=not args.no_progress,
        overwrite=args.overwrite,
    )
    if args.json:
        print_json(result.to_dict())
    else:
        print(format_calibration(result))
    return 0


def _cell(value: Any) -> str:
    return "  n/a" if value is None else f"{value:5.3f}"


def format_calibration(result: Calibration) -> str:
    """The chosen lambda, each fold's choice and AP, and the held-out AP beside the default and the baselines."""
    from energy_margin.evaluation.metrics import verdict_cell

    questions = ("capture_ap", "capture_ap_window2", "success_ap", "success_ap_first_half")
    headings = ("capture k0", "capture k2", "success last", "success 1st half")
    lines = [
        f"chosen on all trajectories: lambda {result.likelihood_lambda:g} 1/J, wrench scale {result.wrench_scale:g}, "
        f"duration scale {result.duration_scale:g} (the task's own lambda: {result.default_lambda:g}); "
        f"objective: mean AP of {', '.join(result.objective)}",
        "fold  trajectories  lambda  wrench  duration  " + "  ".join(f"{heading:>16s}" for heading in headings),
    ]
    for number, fold in enumerate(result.folds):
        cells = "  ".join(f"{_cell(fold['held_out'][q]):>16s}" for q in questions)
        lines.append(
            f"{number:4d}  {len(fold['trajectories']):12d}  {fold['likelihood_lambda']:6g}  "
            f"{fold['wrench_scale']:6g}  {fold['duration_scale']:8g}  {cells}"
        )
    lines.append("AP on every trajectory (calibrated: each scored at the lambda chosen without it):")
    rows = [
        ("calibrated, held out", result.held_out),
        (f"task's lambda {result.default_lambda:g}", result.default),
        *result.baselines.items(),
    ]
    for label, values in rows:
        lines.append(f"  {label:28s} " + "  ".join(f"{_cell(values[q]):>16s}" for q in questions))
    lines.append("calibrated - best baseline [95 % paired interval]:")
    for question in questions:
        lines.append(f"  {question:24s} {verdict_cell(result.verdict[question])}")
    return "\n".join(lines)
