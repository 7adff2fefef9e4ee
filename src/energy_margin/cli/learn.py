"""``energy-margin learn``: fit a learned margin to analysed datasets and report it on held-out trajectories."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from energy_margin.cli.common import add_seed, positive_int, print_json
from energy_margin.errors import EnergyMarginError

NAME = "learn"
SUMMARY = "fit a learned margin (MLP or boosted trees) to analysed datasets; held-out R² and AP"
EXAMPLES = (
    "energy-margin learn runs/push10 --out runs/push10-margin.npz",
    "energy-margin learn runs/push10 runs/push10-b --out model.npz --kind boosting --seed 1 --json",
)
KINDS = ("mlp", "boosting")
#: The AP questions of the report, as ``evaluate`` asks them.
AP_ROWS = (
    ("capture", "capture, k-hat=0"),
    ("capture_window2", "capture, k-hat=2"),
    ("success", "success, last frames"),
    ("success_first_half", "success, first half"),
)


def _fraction(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a fraction in (0, 1), got {text!r}") from None
    if not 0.0 < value < 1.0:
        raise argparse.ArgumentTypeError(f"expected a fraction in (0, 1), got {text!r}")
    return value


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``learn``."""
    parser.add_argument("datasets", nargs="+", metavar="DIR", help="analysed dataset directories of one task")
    parser.add_argument("--out", required=True, metavar="MODEL", help="model file to write (.npz)")
    parser.add_argument("--kind", choices=KINDS, default="mlp", help="regressor: mlp (default) or boosting")
    add_seed(parser)
    parser.add_argument(
        "--holdout", type=_fraction, default=0.25, help="fraction of trajectories held out (default 0.25)"
    )
    parser.add_argument(
        "--success-frames", type=positive_int, default=3, help="k-bar of the trajectory success AP (default 3)"
    )
    parser.add_argument("--overwrite", action="store_true", help="replace an existing model file")
    parser.add_argument("--json", action="store_true", help="print the report as one JSON object")


def _cell(value: float | None, digits: int = 3) -> str:
    return "n/a" if value is None else f"{value:.{digits}f}"


def format_report(report: dict[str, Any], out: Path) -> str:
    """The report of :func:`~energy_margin.learning.margin_model.fit_margin_model` as text."""
    r2, ap = report["r2"], report["ap"]
    return "\n".join(
        [
            f"{report['kind']} margin model of task {report['task']!r} -> {out}",
            f"trajectories: {report['n_trajectories']['train']} train, {report['n_trajectories']['held_out']} held out "
            f"({report['n_frames']['held_out']} frames, split by trajectory); {report['n_features']} features "
            f"({report['feature_set']})",
            f"held-out R²: capture {_cell(r2['capture'])}, success {_cell(r2['success'])}",
            "held-out AP             learned  tree (true scores)",
            *(f"  {label:<20}  {_cell(ap[key]['learned']):>7}  {_cell(ap[key]['tree'])}" for key, label in AP_ROWS),
            f"per query: {report['seconds_per_query'] * 1e6:.1f} µs batched, "
            f"{report['seconds_single_query'] * 1e6:.1f} µs for one frame "
            f"(CPU {report['cpu_seconds_per_query'] * 1e6:.1f} and {report['cpu_seconds_single_query'] * 1e6:.1f} µs); "
            f"tree {report['tree_seconds_per_frame']:.3f} s per frame in the analysis "
            f"({report['speedup']:.0f}x batched, {report['speedup_single_query']:.0f}x one frame)",
        ]
    )


def run(args: argparse.Namespace) -> int:
    """Fit, save and report."""
    from energy_margin.learning.margin_model import fit_margin_model, load_training_datasets

    out = Path(args.out)
    if out.is_dir():
        raise EnergyMarginError(f"--out {out} is a directory; give a model file name, e.g. model.npz")
    if out.exists() and not args.overwrite:
        raise EnergyMarginError(f"{out} already exists; pass --overwrite to replace it")
    datasets = load_training_datasets(args.datasets)
    model, report = fit_margin_model(
        datasets, seed=args.seed, kind=args.kind, holdout=args.holdout, success_frames=args.success_frames
    )
    model.save(out)
    if args.json:
        print_json({**report, "out": str(out)})
    else:
        print(format_report(report, out))
    return 0
