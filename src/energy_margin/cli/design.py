"""``energy-margin design``: black-box search of a task's design by its energy margin, then verification."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import Any

from energy_margin.cli.common import (
    add_engine,
    add_old_spelling,
    add_overwrite,
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
    "SCORES",
    "SUMMARY",
    "add_arguments",
    "draw_design",
    "run",
]

NAME = "design"
SUMMARY = "search a task's design by its energy margin (CMA-ES, TPE or a grid), then verify it by control episodes"
EXAMPLES = (
    "energy-margin design --task scooping --param scoop_angle=1.0:1.5 --param open_gap=0.07:0.11 --optimizer cma "
    "--evaluations 30 --objects 5 --verify 50 --seed 0 --out runs/design-scoop --workers 2",
    "energy-margin design --task pushing --param pusher_width=0.4:1.0 --optimizer tpe --evaluations 20 "
    "--objects 5 --verify 100 --out runs/design-push --json",
    "energy-margin design --task pushing --param pusher_width=0.4:1.0 --objective learned --model runs/push.margin "
    "--optimizer grid --evaluations 12 --objects 5 --verify 50 --out runs/design-push-learned",
)
#: Keyword arguments of :func:`~energy_margin.design.search.design_search` named otherwise here.
PARAMETER_FLAGS = {
    "n_trajectories": "--trajectories",
    "n_frames": "--frames",
    "n_objects": "--objects",
    "score": "--score",
    "policy": "--policy",
    "params": "--param",
    "fixed": "--set",
}
#: ``--score`` names and the score columns they stand for.
SCORES = {"success": "success_score", "early": "early_success_score", "capture": "capture_score"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``design``: what is searched and how, how a design is scored, verified, and the run."""
    _add_search(parser)
    _add_scoring(parser)
    _add_verification_and_run(parser)


def _add_search(parser: argparse.ArgumentParser) -> None:
    """The task or scene, the axes of the search, the optimiser and its objective."""
    from energy_margin.design.optimizers import OPTIMIZERS
    from energy_margin.tasks import available_tasks

    tasks = available_tasks()
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--task", choices=tasks, help=f"registered task: {', '.join(tasks)}")
    where.add_argument("--scene", metavar="SCENE.toml", help="a scene file (instead of --task)")
    parser.add_argument(
        "--param",
        action="append",
        default=[],
        metavar="NAME=LOW:HIGH|NAME=A,B,C",
        help="an axis of the search: a numeric range or categorical values (repeat for more axes); "
        "without --param, the task's tool family (Task.design_space)",
    )
    parser.add_argument("--optimizer", choices=OPTIMIZERS, default="tpe", help="cma, tpe or grid (default tpe)")
    parser.add_argument(
        "--evaluations", type=non_negative_int, default=30, help="the optimiser's evaluations (default 30)"
    )
    parser.add_argument(
        "--objective",
        choices=("margin", "learned"),
        default="margin",
        help="margin: the tree at --expansions expansions a frame; learned: the learned margin of --model",
    )
    parser.add_argument("--model", help="learned margin file (energy-margin learn), for --objective learned")
    parser.add_argument(
        "--score",
        choices=tuple(SCORES),
        default="success",
        help="the score averaged over the roll-outs: success (all frames, default), early (first half) or capture",
    )


def _add_scoring(parser: argparse.ArgumentParser) -> None:
    """The roll-outs of one evaluation and the trees that score them."""
    from energy_margin.design.scorers import DESIGN_EXPANSIONS, DESIGN_FRAMES, DESIGN_TRAJECTORIES
    from energy_margin.planning.costs import COST_MODELS
    from energy_margin.planning.methods import METHODS

    parser.add_argument(
        "--trajectories",
        type=positive_int,
        default=DESIGN_TRAJECTORIES,
        help=f"roll-outs per evaluation (default {DESIGN_TRAJECTORIES})",
    )
    parser.add_argument(
        "--frames", type=positive_int, default=DESIGN_FRAMES, help=f"frames per roll-out (default {DESIGN_FRAMES})"
    )
    parser.add_argument("--objects", type=positive_int, help="objects per scene")
    add_old_spelling(
        parser,
        "--iterations",
        parser.add_argument(
            "--expansions",
            type=positive_int,
            default=DESIGN_EXPANSIONS,
            help=f"expansions per frame (default {DESIGN_EXPANSIONS})",
        ),
    )
    parser.add_argument("--method", choices=METHODS, default="est", help=f"tree method: {', '.join(METHODS)}")
    parser.add_argument("--cost", choices=tuple(COST_MODELS), default="wrench", help="incremental cost model")


def _add_verification_and_run(parser: argparse.ArgumentParser) -> None:
    """The closed-loop verification of the chosen design, and the run directory."""
    from energy_margin.control.disturbances import DISTURBANCES
    from energy_margin.design.verification import VERIFY_POLICIES

    parser.add_argument(
        "--verify", type=non_negative_int, default=20, help="verification episodes per design and level (default 20)"
    )
    parser.add_argument(
        "--disturbance",
        nargs="+",
        choices=tuple(DISTURBANCES),
        default=["mild", "hard"],
        help="the verification's disturbance levels (default mild hard)",
    )
    parser.add_argument(
        "--policy",
        choices=VERIFY_POLICIES,
        default="scripted",
        help="the verification's policy: scripted (the design's own motion, default) or task (MPPI)",
    )
    parser.add_argument(
        "--verify-all", action="store_true", help="verify every visited design too (the rank correlation over all)"
    )
    add_seed(parser)
    parser.add_argument("--out", required=True, help="run directory (a rerun resumes it)")
    add_overwrite(parser, "a design search of other settings in --out")
    parser.add_argument("--workers", type=positive_int, default=1, help="worker processes (default 1)")
    add_engine(parser, records=True)  # the candidates are generated on it, then analysed
    add_set(parser, "a task setting fixed for every design, e.g. --set drive_jitter=0.1")
    parser.add_argument("--no-picture", action="store_true", help="do not draw the chosen design (tool.png)")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bars")
    parser.add_argument("--json", action="store_true", help="print the result as one JSON object")


def draw_design(dataset_directory: Path, path: Path) -> Path | None:
    """The chosen design at the start of its first roll-out, by the renderer of ``render`` (``None``: no matplotlib).

    The regions are left out: the picture shows the tool and the objects.
    """
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        return None
    from energy_margin.data.dataset import load_dataset
    from energy_margin.report.render import dataset_renderer, save_png

    dataset = load_dataset(dataset_directory)
    with dataset_renderer(dataset, 0) as renderer:
        save_png(renderer.render(dataset.frame(0, 0), regions=False), path)
    return path


def _task(args: argparse.Namespace) -> tuple[str, dict[str, Any]]:
    if args.scene:
        return scene_task_config(args.scene, task_overrides(args.set))
    return args.task, task_overrides(args.set)


def run(args: argparse.Namespace) -> int:
    """Search, verify, print the table (or the JSON object)."""
    from energy_margin.analysis.frame import AnalyzerConfig
    from energy_margin.design.params import parse_param
    from energy_margin.design.search import RESULT_JSON, TreeScorer, design_search, format_result
    from energy_margin.design.verification import EpisodeVerifier
    from energy_margin.tasks import resolve_task

    params = [parse_param(text) for text in args.param]
    task_name, fixed = _task(args)
    task = resolve_task(task_name, fixed)
    extra: dict[str, Any] = {}
    if args.objective == "learned":
        from energy_margin.learning.scoring import LearnedFrameScorer

        if args.scene:
            # Every --scene search sets the file's [design] values, and each design compiles to its own
            # model: a learned margin checks the model's hash, so it would fail every design but one.
            raise EnergyMarginError(
                "--objective learned cannot score a --scene design search: a learned margin model is tied to "
                "the one compiled model it was fitted on and each [design] value compiles another; "
                "use --objective margin"
            )
        if args.model is None:
            raise EnergyMarginError("--objective learned needs --model MODEL (made by energy-margin learn)")
        n_objects = task.fixed_objects or args.objects
        if n_objects is None:
            raise EnergyMarginError(f"{task.label} needs the number of objects (--objects)")
        scorer: Any = LearnedFrameScorer(args.model, task_name=task.name, n_objects=n_objects)
        extra["model_path"] = os.path.abspath(args.model)
    else:
        if args.model is not None:
            raise EnergyMarginError("--model is only for --objective learned")
        analyzer = AnalyzerConfig(expansions=args.expansions, cost=args.cost, method=args.method, engine=args.engine)
        scorer = TreeScorer(analyzer)
    progress = (
        not args.no_progress
        and not args.json
        and (sys.stderr.isatty() or os.environ.get("ENERGY_MARGIN_PROGRESS") == "1")
    )
    result = design_search(
        task,
        params,
        optimizer=args.optimizer,
        evaluations=args.evaluations,
        verify=args.verify,
        out=args.out,
        n_objects=args.objects,
        n_trajectories=args.trajectories,
        n_frames=args.frames,
        seed=args.seed,
        score=SCORES[args.score],
        scorer=scorer,
        verifier=EpisodeVerifier(args.policy),
        disturbances=args.disturbance,
        verify_all=args.verify_all,
        engine=args.engine,
        fixed=fixed,
        workers=args.workers,
        overwrite=args.overwrite,
        progress=progress,
        picture=None if args.no_picture else draw_design,
        extra_settings=extra,
    )
    if args.json:
        print_json(result.to_dict())
    else:
        print(format_result(result))
        print(
            f"wrote {os.path.join(args.out, RESULT_JSON)} (CSV, the search figure and the design's picture beside it)"
        )
    return 0
