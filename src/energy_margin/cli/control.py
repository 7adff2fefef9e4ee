"""``energy-margin control``: closed-loop episodes of a policy under disturbances, written as a dataset."""

from __future__ import annotations

import argparse
import hashlib
from pathlib import Path
from typing import Any

from energy_margin.cli.common import (
    add_old_spelling,
    add_seed,
    add_set,
    non_negative_int,
    positive_int,
    print_json,
    scene_task_config,
    task_overrides,
)
from energy_margin.errors import EnergyMarginError

__all__ = [
    "EXAMPLES",
    "NAME",
    "PARAMETER_FLAGS",
    "SUMMARY",
    "add_arguments",
    "controller_default",
    "format_summary",
    "run",
]

NAME = "control"
SUMMARY = "closed-loop episodes (MPPI with task, heuristic or margin costs) under disturbances"
EXAMPLES = (
    "energy-margin control --task pushing --objects 5 --episodes 100 --policy margin "
    "--disturbance hard --seed 0 --out runs/control-margin --workers 2",
    "energy-margin control --task pushing --objects 10 --episodes 100 --policy learned "
    "--model runs/push10.margin --disturbance hard --out runs/control-learned --json",
)
#: Keyword arguments of :func:`~energy_margin.control.episodes.run_control` named otherwise here.
PARAMETER_FLAGS = {"n_objects": "--objects", "n_frames": "--frames"}


def controller_default(name: str) -> Any:
    """The default of :class:`~energy_margin.control.mppi.ControllerConfig`'s field ``name``: the option's too."""
    from energy_margin.control.mppi import ControllerConfig
    from energy_margin.errors import field_default

    return field_default(ControllerConfig, name)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``control``."""
    from energy_margin.control.commands import controllable_tasks
    from energy_margin.control.disturbances import DISTURBANCES
    from energy_margin.control.episodes import POLICIES

    parser.add_argument("--task", default="pushing", help=f"task: {', '.join(controllable_tasks())} (default pushing)")
    parser.add_argument(
        "--scene", metavar="SCENE.toml", help="a scene file driven by actuator controls (instead of --task)"
    )
    parser.add_argument(
        "--objects", type=positive_int, default=None, help="objects per episode (default 5; a scene file's own)"
    )
    parser.add_argument("--episodes", type=positive_int, default=100, help="episodes (default 100)")
    parser.add_argument(
        "--policy", choices=POLICIES, default="task", help=f"policy: {', '.join(POLICIES)} (default task)"
    )
    parser.add_argument("--model", help="learned margin file (energy-margin learn), for --policy learned")
    parser.add_argument(
        "--disturbance",
        choices=tuple(DISTURBANCES),
        default="mild",
        help=f"what the controller's model does not know: {', '.join(DISTURBANCES)} (default mild)",
    )
    add_seed(parser)
    parser.add_argument("--out", required=True, help="run directory: the episodes' dataset and control.json")
    parser.add_argument("--frames", type=positive_int, default=10, help="frames recorded per episode (default 10)")
    add_old_spelling(
        parser,
        "--score-expansions",
        parser.add_argument(
            "--expansions",
            type=non_negative_int,
            default=30,
            help="expansions of the analysis of each recorded frame, for the mean capture score (0: skip; default 30)",
        ),
    )
    default = controller_default
    parser.add_argument(
        "--samples",
        type=positive_int,
        default=default("samples"),
        help=f"MPPI samples per decision (default {default('samples')})",
    )
    parser.add_argument(
        "--horizon",
        type=positive_int,
        default=default("horizon"),
        help=f"MPPI horizon in periods (default {default('horizon')})",
    )
    parser.add_argument(
        "--period", type=float, default=default("period"), help=f"control period, s (default {default('period'):g})"
    )
    parser.add_argument(
        "--lookahead",
        type=non_negative_int,
        default=default("lookahead"),
        help="periods the prediction goes on past the horizon with the script's commands, cut at the "
        f"episode's end; the cost sees those states too (default {default('lookahead')})",
    )
    parser.add_argument(
        "--margin-expansions",
        type=positive_int,
        default=default("margin_expansions"),
        help=f"expansions per margin analysis (default {default('margin_expansions')})",
    )
    parser.add_argument(
        "--margin-samples",
        type=positive_int,
        default=default("margin_samples"),
        help=f"samples analysed per decision (default {default('margin_samples')})",
    )
    parser.add_argument("--margin-weight", type=float, default=2.0, help="weight of the scores in the cost (default 2)")
    add_set(parser, "override a task setting, e.g. --set friction_range=[0.1,0.2]")
    parser.add_argument("--workers", type=positive_int, default=1, help="parallel processes (default 1)")
    parser.add_argument("--overwrite", action="store_true", help="replace a run of other settings in --out")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    parser.add_argument("--json", action="store_true", help="print the summary as one JSON object")


def _load_model(path: str, task_name: str) -> tuple[Any, dict[str, Any]]:
    """The learned margin at ``path`` and what identifies it."""
    from energy_margin.learning.margin_model import load_margin_model

    model = load_margin_model(path, task_name=task_name)
    digest = hashlib.sha256(Path(path).read_bytes()).hexdigest() if Path(path).is_file() else None
    return model, {"path": str(path), "sha256": digest}


def format_summary(summary: dict[str, Any]) -> str:
    """The summary as a few human-readable lines."""
    low, high = summary["success_interval"]
    lines = [
        f"{summary['task']}, {summary['n_objects']} objects, policy {summary['policy']}, "
        f"disturbance {summary['disturbance']}: {summary['episodes']} episodes",
        f"  success rate {summary['success_rate']:.3f} ({summary['successes']}/{summary['episodes']}), "
        f"95 % Wilson interval [{low:.3f}, {high:.3f}]",
        f"  captured frames {summary['captured_fraction']:.3f}",
    ]
    if summary["mean_capture_score"] is not None:
        lines.append(f"  mean capture score along the episodes {summary['mean_capture_score']:.3f}")
    if summary["seconds_per_decision"] is not None:
        lines.append(
            f"  {summary['seconds_per_decision'] * 1000:.1f} ms per decision ({summary['decisions']} decisions)"
        )
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Run or resume the episodes and print their summary."""
    from energy_margin.control.costs import CostWeights
    from energy_margin.control.episodes import run_control
    from energy_margin.control.mppi import ControllerConfig

    controller = ControllerConfig(
        samples=args.samples,
        horizon=args.horizon,
        period=args.period,
        lookahead=args.lookahead,
        margin_expansions=args.margin_expansions,
        margin_samples=args.margin_samples,
    )
    if args.scene:
        task_name, overrides = scene_task_config(args.scene, task_overrides(args.set))
    else:
        task_name, overrides = args.task, task_overrides(args.set)
    n_objects = args.objects
    if n_objects is None:
        from energy_margin.tasks import get_task

        n_objects = (get_task(task_name, overrides or None).fixed_objects or 5) if args.scene else 5
    model, model_info = (None, None)
    if args.model is not None:
        if args.policy != "learned":
            raise EnergyMarginError("--model is only for --policy learned")
        model, model_info = _load_model(args.model, task_name)
    result, dataset = run_control(
        task_name,
        n_objects=n_objects,
        episodes=args.episodes,
        policy=args.policy,
        disturbance=args.disturbance,
        seed=args.seed,
        out=args.out,
        task_overrides=overrides,
        controller=controller,
        weights=CostWeights(margin=args.margin_weight),
        n_frames=args.frames,
        score_expansions=args.expansions,
        model=model,
        model_info=model_info,
        workers=args.workers,
        overwrite=args.overwrite,
        progress=not args.no_progress and not args.json,
    )
    summary = result.to_dict()
    dropped = dataset.metadata.get("dropped") or []
    if args.json:
        # The run's summary, and the episodes left out of the dataset when there are any.
        print_json({**summary, "dropped": dropped} if dropped else summary)
        return 0
    print(format_summary(summary))
    if dropped:
        print(
            f"left out of the dataset {len(dropped)} episode(s) with a physically impossible frame (listed in "
            f"dataset.json's dropped; the first: {dropped[0]['rollout']}: {dropped[0]['reason']}); the summary "
            "counts every episode"
        )
    print(f"wrote {args.out} (energy-margin analyze {args.out} scores its frames)")
    return 0
