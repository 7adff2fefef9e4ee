"""``energy-margin learn``: fit a learned margin to analysed datasets and report it on held-out trajectories.

Two forms: analysed dataset directories (``learn DIR... --out MODEL``), or a task or scene file
whose datasets the command generates and analyses first in a resumable work directory
(``learn --task T --objects 5,10 --trajectories N --work DIR --out MODEL``,
:func:`energy_margin.learning.pipeline.learn_pipeline`).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import Any

from energy_margin.cli.common import add_old_spelling, add_seed, positive_int, print_json
from energy_margin.errors import EnergyMarginError
from energy_margin.learning.margin_model import DEFAULT_KIND, KINDS
from energy_margin.tasks import available_tasks

__all__ = [
    "AP_ROWS",
    "DEFAULT_FRAMES",
    "EXAMPLES",
    "NAME",
    "PIPELINE_OPTIONS",
    "SUMMARY",
    "add_arguments",
    "format_report",
    "run",
]

NAME = "learn"
SUMMARY = (
    "fit a learned margin to analysed datasets, or generate, analyse and fit in one resumable run; held-out R² and AP"
)
EXAMPLES = (
    "energy-margin learn runs/push10 --out runs/push10-margin.npz",
    "energy-margin learn runs/push10 runs/push10-b --out model.npz --kind boosting --seed 1 --json",
    "energy-margin learn --task pushing --objects 5,10,20 --trajectories 100 --frames 10 --work runs/learn-push "
    "--out push.npz --workers 2",
    "energy-margin learn --scene my_scene.toml --trajectories 60 --work runs/learn-mine --out mine.npz",
)
#: The AP questions of the report, as ``evaluate`` asks them.
AP_ROWS = (
    ("capture", "capture, k-hat=0"),
    ("capture_window2", "capture, k-hat=2"),
    ("success", "success, last frames"),
    ("success_first_half", "success, first half"),
)
#: Options of the generating form only (``--task`` / ``--scene``), by ``dest``.
PIPELINE_OPTIONS = {
    "objects": "--objects",
    "trajectories": "--trajectories",
    "frames": "--frames",
    "work": "--work",
    "workers": "--workers",
    "expansions": "--expansions",
    "no_progress": "--no-progress",
}
DEFAULT_FRAMES = 10


def _fraction(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a fraction in (0, 1), got {text!r}") from None
    if not 0.0 < value < 1.0:
        raise argparse.ArgumentTypeError(f"expected a fraction in (0, 1), got {text!r}")
    return value


def _object_counts(text: str) -> list[int]:
    """``5,10,20``: distinct numbers of objects, each >= 1."""
    counts = []
    for part in text.split(","):
        try:
            counts.append(positive_int(part.strip()))
        except argparse.ArgumentTypeError as error:
            raise argparse.ArgumentTypeError(
                f"expected a comma list of integers >= 1, got {text!r} ({error})"
            ) from None
    if len(set(counts)) != len(counts):
        raise argparse.ArgumentTypeError(f"expected distinct numbers of objects, got {text!r}")
    return counts


def _trajectories(text: str) -> int:
    """An integer >= 2: the fit holds whole trajectories out."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if value < 2:
        raise argparse.ArgumentTypeError(f"expected an integer >= 2 (the fit holds trajectories out), got {value}")
    return value


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``learn``."""
    from energy_margin.cli.analyze import DEFAULT_EXPANSIONS

    tasks = available_tasks()
    parser.add_argument(
        "datasets", nargs="*", metavar="DIR", help="analysed dataset directories of one task (or --task / --scene)"
    )
    source = parser.add_mutually_exclusive_group()
    source.add_argument(
        "--task", choices=tasks, help=f"generate, analyse and fit datasets of a registered task: {', '.join(tasks)}"
    )
    source.add_argument("--scene", metavar="SCENE.toml", help="generate, analyse and fit datasets of a scene file")
    parser.add_argument("--out", required=True, metavar="MODEL", help="model file to write (.npz)")
    parser.add_argument(
        "--kind",
        choices=KINDS,
        default=DEFAULT_KIND,
        help=f"regressor: {', '.join(KINDS)} (default {DEFAULT_KIND}: the network over the objects, fitted "
        "with PyTorch, the learn extra)",
    )
    add_seed(parser)
    parser.add_argument(
        "--holdout", type=_fraction, default=0.25, help="fraction of trajectories held out (default 0.25)"
    )
    parser.add_argument(
        "--success-frames", type=positive_int, default=3, help="k-bar of the trajectory success AP (default 3)"
    )
    parser.add_argument(
        "--overwrite",
        action="store_true",
        help="replace an existing model file (and, with --work, a run of other settings there)",
    )
    parser.add_argument("--json", action="store_true", help="print the report as one JSON object")
    generating = parser.add_argument_group("generating form (--task or --scene)")
    generating.add_argument(
        "--objects",
        type=_object_counts,
        default=None,
        metavar="N[,N...]",
        help="objects per scene, one dataset per number (default the task's typical number; not with --scene)",
    )
    generating.add_argument(
        "--trajectories", type=_trajectories, default=None, help="trajectories per dataset (required, >= 2)"
    )
    generating.add_argument(
        "--frames", type=positive_int, default=None, help=f"frames per trajectory (default {DEFAULT_FRAMES})"
    )
    generating.add_argument(
        "--work", metavar="DIR", default=None, help="work directory of the datasets, their scores and the run (resumes)"
    )
    generating.add_argument("--workers", type=positive_int, default=None, help="analysis worker processes (default 1)")
    add_old_spelling(
        generating,
        "--iterations",
        generating.add_argument(
            "--expansions",
            type=positive_int,
            default=None,
            help=f"analysis expansions per frame (default {DEFAULT_EXPANSIONS})",
        ),
    )
    generating.add_argument("--no-progress", action="store_true", help="hide the progress bars")


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


def _form(args: argparse.Namespace) -> str:
    """``"datasets"``, ``"task"`` or ``"scene"``: the form the arguments ask for, checked."""
    given = [
        name
        for name, present in (
            ("dataset directories", bool(args.datasets)),
            ("--task", args.task),
            ("--scene", args.scene),
        )
        if present
    ]
    if len(given) != 1:
        what = " and ".join(given) if given else "nothing to learn from"
        raise EnergyMarginError(
            f"learn takes analysed dataset directories, --task or --scene (exactly one); got {what}"
        )
    if args.datasets:
        extra = [flag for dest, flag in PIPELINE_OPTIONS.items() if getattr(args, dest) not in (None, False)]
        if extra:
            raise EnergyMarginError(f"{extra[0]} applies to --task or --scene, not to analysed dataset directories")
        return "datasets"
    source = "--task" if args.task else "--scene"
    if args.work is None:
        raise EnergyMarginError(f"{source} needs --work DIR: the directory that keeps the datasets and resumes")
    if args.trajectories is None:
        raise EnergyMarginError(f"{source} needs --trajectories N: trajectories per generated dataset (>= 2)")
    if args.scene and args.objects is not None:
        raise EnergyMarginError(f"--objects does not apply to --scene {args.scene}: a scene file fixes its objects")
    if args.scene and not os.path.isfile(args.scene):
        raise EnergyMarginError(f"scene file {args.scene} does not exist")
    return source[2:]


def run(args: argparse.Namespace) -> int:
    """Fit (after generating and analysing, in the --task / --scene form), save and report."""
    form = _form(args)
    out = Path(args.out)
    extra: dict[str, Any] = {}
    if form == "datasets":
        report = _fit_datasets(args, out)
    else:
        from energy_margin.learning.pipeline import learn_pipeline

        progress = not args.no_progress and (sys.stderr.isatty() or os.environ.get("ENERGY_MARGIN_PROGRESS") == "1")
        result = learn_pipeline(
            args.work,
            out,
            task=args.task,
            scene=args.scene,
            objects=args.objects,
            n_trajectories=args.trajectories,
            n_frames=args.frames if args.frames is not None else DEFAULT_FRAMES,
            seed=args.seed,
            workers=args.workers if args.workers is not None else 1,
            expansions=args.expansions,
            kind=args.kind,
            holdout=args.holdout,
            success_frames=args.success_frames,
            overwrite=args.overwrite,
            progress=progress,
        )
        report = result.report.to_dict()
        extra = {
            "work": str(result.work),
            "fit_seed": result.fit_seed,
            "sets": [item.to_dict() for item in result.sets],
            "resumed": result.resumed,
            "seconds": result.seconds,
        }
    if args.json:
        print_json({**report, "out": str(out), **extra})
    else:
        print(format_report(report, out))
    return 0


def _fit_datasets(args: argparse.Namespace, out: Path) -> dict[str, Any]:
    """Today's form: fit analysed dataset directories and save the model; the report."""
    from energy_margin.learning.margin_model import fit_margin_model, load_training_datasets

    if out.is_dir():
        raise EnergyMarginError(f"--out {out} is a directory; give a model file name, e.g. model.npz")
    if out.exists() and not args.overwrite:
        raise EnergyMarginError(f"{out} already exists; pass --overwrite to replace it")
    datasets = load_training_datasets(args.datasets)
    model, report = fit_margin_model(
        datasets, seed=args.seed, kind=args.kind, holdout=args.holdout, success_frames=args.success_frames
    )
    model.save(out)
    return report.to_dict()
