"""``energy-margin analyze``: score every frame of a dataset with energy margins.

Trees are grown for every frame (:func:`energy_margin.analysis.run.analyze`), or, with ``--model``,
a learned margin predicts the scores (:func:`energy_margin.learning.scoring.score_dataset`); both
write ``scores.csv`` beside the dataset.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from energy_margin.analysis.executors import EXECUTORS
from energy_margin.analysis.frame import ANALYSIS_MODELS, CONVERGE_RULES, DEVICES, AnalyzerConfig
from energy_margin.analysis.scores import CAPTURE_GATES
from energy_margin.cli.common import (
    add_engine,
    add_old_spelling,
    add_seed,
    analyzer_default,
    non_negative_float,
    non_negative_int,
    positive_float,
    positive_int,
    say_notes,
)
from energy_margin.data.scores_file import CONFIG_FILE
from energy_margin.errors import EnergyMarginError
from energy_margin.planning.costs import COST_MODELS
from energy_margin.planning.density import PROJECTIONS
from energy_margin.planning.methods import METHODS
from energy_margin.runs.files import read_json
from energy_margin.sim import check_engine_device
from energy_margin.tasks.base import CONTACT_MODELS

if TYPE_CHECKING:
    from energy_margin.data.dataset import Dataset

__all__ = [
    "COSTS",
    "DEFAULT_EXPANSIONS",
    "EXAMPLES",
    "NAME",
    "SUMMARY",
    "TREE_ONLY",
    "add_arguments",
    "analyzer_config",
    "calibrated_settings",
    "default",
    "run",
    "run_learned",
    "tree_options_given",
]

NAME = "analyze"
SUMMARY = "score every frame of a dataset: capture and success scores into scores.csv"
EXAMPLES = (
    "energy-margin analyze runs/push10 --expansions 300 --workers 2 --seed 0",
    "energy-margin analyze runs/push10 --nodes 200 --cost energy --overwrite",
    "energy-margin analyze runs/push10-perturbed --model runs/push10-margin.npz",
)
# The choices are the registries themselves, so a new method or cost model shows up here.
COSTS = tuple(COST_MODELS)
default = analyzer_default


#: The expansions per frame without ``--expansions`` and ``--nodes`` (AnalyzerConfig's own).
DEFAULT_EXPANSIONS = default("expansions")
#: The options of the tree analysis (by ``dest``): a learned margin (``--model``) grows no tree.
TREE_ONLY = {
    "expansions": "--expansions",
    "nodes": "--nodes",
    "cost": "--cost",
    "likelihood_lambda": "--lambda",
    "calibration": "--calibration",
    "wrench_scale": "--wrench-scale",
    "duration_scale": "--duration-scale",
    "workers": "--workers",
    "executor": "--executor",
    "address": "--address",
    "engine": "--engine",
    "device": "--device",
    "method": "--method",
    "batch": "--batch",
    "threads": "--threads",
    "converge": "--converge",
    "converge_rule": "--converge-rule",
    "contacts": "--contacts",
    "analysis_model": "--analysis-model",
    "projection": "--projection",
    "continuation": "--continuation",
    "continuation_horizon": "--continuation-horizon",
    "capture_gate": "--capture-gate",
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``analyze``: the dataset, the tree's budget and scoring, the run, the tree's growth."""
    parser.add_argument("dataset", help="dataset directory")
    _add_budget_and_scoring(parser)
    _add_run(parser)
    _add_growth(parser)


def _add_budget_and_scoring(parser: argparse.ArgumentParser) -> None:
    """How far each frame's tree grows and how its states are scored."""
    add_old_spelling(
        parser,
        "--iterations",
        parser.add_argument(
            "--expansions",
            type=non_negative_int,
            default=None,
            help=f"expansions per frame (default {DEFAULT_EXPANSIONS} when --nodes is absent)",
        ),
    )
    parser.add_argument("--nodes", type=non_negative_int, default=default("nodes"), help="tree nodes per frame")
    parser.add_argument(
        "--capture-gate",
        choices=CAPTURE_GATES,
        default=default("capture_gate"),
        help="current (default): a frame whose objects are not all in its capture region scores capture 0 (they "
        "are lost already); none: the tree's likelihood mass alone, the paper's score (reproduce uses it)",
    )
    parser.add_argument(
        "--cost",
        choices=COSTS,
        default=default("cost"),
        help=f"incremental cost: wrench (perturbation work) or energy (|dE - W_fri|) (default {default('cost')})",
    )
    parser.add_argument(
        "--lambda",
        dest="likelihood_lambda",
        type=non_negative_float,
        default=default("likelihood_lambda"),
        help="softmax inverse temperature, 1/J (default: the task's)",
    )
    parser.add_argument(
        "--wrench-scale",
        type=positive_float,
        default=default("wrench_scale"),
        help=f"factor on the task's perturbation wrench bounds (default {default('wrench_scale'):g})",
    )
    parser.add_argument(
        "--duration-scale",
        type=positive_float,
        default=default("duration_scale"),
        help=f"factor on the task's longest perturbation propagation (default {default('duration_scale'):g})",
    )
    parser.add_argument(
        "--calibration",
        default=None,
        metavar="FILE",
        help="calibration.json of energy-margin calibrate: analyse at the lambda it chose (not with --lambda)",
    )
    parser.add_argument(
        "--continuation",
        type=_continuation,
        default=default("continuation"),
        metavar="K|auto",
        help="success continuation: score success by the fraction of K nodes, drawn by likelihood, whose "
        "unperturbed scripted motion ends in the success region (mujoco engines); 0: the tree's own score; "
        "default auto: 16 where the engine continues, else 0",
    )
    parser.add_argument(
        "--continuation-horizon",
        type=positive_float,
        default=default("continuation_horizon"),
        metavar="SECONDS",
        help="longest continuation past its node, s (default: to the end of the task's motion)",
    )


def _continuation(text: str) -> int | None:
    """``auto`` (None: analyze's rule decides) or an integer >= 0."""
    return None if text == "auto" else non_negative_int(text)


def _add_run(parser: argparse.ArgumentParser) -> None:
    """Where and how the frames are analysed, and the learned margin instead of trees."""
    parser.add_argument("--workers", type=positive_int, default=1, help="parallel workers (default 1)")
    parser.add_argument("--executor", choices=EXECUTORS, default="local", help="local process pool (default) or Ray")
    parser.add_argument("--address", default=None, help="Ray cluster address (default: start a local Ray)")
    add_seed(parser)
    add_engine(parser)
    parser.add_argument(
        "--device",
        choices=DEVICES,
        default=None,
        help="where engine mujoco-warp runs: cuda (default) or cpu (slow; for checks); other engines run on the CPU",
    )
    parser.add_argument("--overwrite", action="store_true", help="replace scores of another configuration")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    parser.add_argument(
        "--model",
        default=None,
        metavar="MODEL",
        help="learned margin file (energy-margin learn): predict every frame's scores with it instead of "
        "growing trees (takes none of the tree options)",
    )


def _add_growth(parser: argparse.ArgumentParser) -> None:
    """How each tree grows: its method, batches, adaptive budget, contacts and density features."""
    parser.add_argument(
        "--method",
        choices=METHODS,
        default=default("method"),
        help=f"tree method: {', '.join(METHODS)} (default {default('method')})",
    )
    parser.add_argument(
        "--batch",
        type=positive_int,
        default=default("batch"),
        help=f"expansions per mujoco.rollout round (default {default('batch')}; with --converge it loses AP: "
        "docs/results/performance.md)",
    )
    parser.add_argument(
        "--threads",
        type=positive_int,
        default=default("threads"),
        help=f"mujoco.rollout threads (default {default('threads')})",
    )
    parser.add_argument(
        "--converge",
        type=non_negative_float,
        default=default("converge"),
        metavar="TOL",
        help="adaptive budget: stop a frame once neither score would move by more than TOL by the end of the "
        "budget at its rate over the last 50 expansions (the budget stays the upper bound; default: spend the "
        "whole budget; 0.02 holds AP on the sets it was chosen on, but costs 0.013-0.019 of future-capture AP "
        "on a 5-object set it was not: docs/results/performance.md)",
    )
    parser.add_argument(
        "--converge-rule",
        choices=CONVERGE_RULES,
        default=default("converge_rule"),
        help="rule of --converge: projected (default), window (neither score moved by more than TOL over "
        "the last 50 expansions; stops earlier, biased high) or projected-reached (projected once the success "
        "score has left 0)",
    )
    parser.add_argument(
        "--contacts",
        choices=CONTACT_MODELS,
        default=default("contacts"),
        help="contact model: the dataset's (recorded, default) or the task's fast one (pushing: one ground "
        "contact per cylinder and sphere stand-ins for the lateral pairs; the same contacts, cheaper)",
    )
    parser.add_argument(
        "--analysis-model",
        choices=ANALYSIS_MODELS,
        default=default("analysis_model"),
        help="pruned (default): simulate the model less the contact pairs that cannot move an object (robot "
        "self-collision; robot-world pairs for a robot held still), exact while no dropped pair touches; full: "
        "the model as it is",
    )
    parser.add_argument(
        "--projection",
        choices=PROJECTIONS,
        default=default("projection"),
        help="EST density features: every object's centre, or the ellipsoid of the centres "
        f"(default {default('projection')})",
    )


def calibrated_settings(args: argparse.Namespace) -> dict[str, float]:
    """The settings of ``--calibration`` for the dataset's task: lambda and the growth scales.

    Raises:
        EnergyMarginError: ``--lambda`` or a scale too, an unreadable dataset, or a calibration
            that is not one, is unfinished or is of another task.
    """
    from pathlib import Path

    from energy_margin.data.dataset import METADATA_FILE, read_json
    from energy_margin.evaluation.calibration import read_calibration

    if args.likelihood_lambda is not None:
        raise EnergyMarginError("--calibration and --lambda both set lambda: give one")
    if args.wrench_scale != 1.0 or args.duration_scale != 1.0:
        raise EnergyMarginError("--calibration sets the growth scales: leave --wrench-scale and --duration-scale out")
    metadata = read_json(Path(args.dataset) / METADATA_FILE, what=METADATA_FILE)
    task = metadata.get("task") if isinstance(metadata, dict) else None
    return read_calibration(args.calibration, task=str(task))


def analyzer_config(args: argparse.Namespace) -> AnalyzerConfig:
    """The :class:`~energy_margin.analysis.frame.AnalyzerConfig` the arguments ask for."""
    if args.expansions == 0 and args.nodes is None:
        raise EnergyMarginError("--expansions 0 grows no tree: give a positive number or a --nodes budget")
    expansions = args.expansions if args.expansions is not None or args.nodes is not None else DEFAULT_EXPANSIONS
    chosen = {
        "likelihood_lambda": args.likelihood_lambda,
        "wrench_scale": args.wrench_scale,
        "duration_scale": args.duration_scale,
    }
    continuation = args.continuation
    if getattr(args, "calibration", None) is not None:
        calibrated = calibrated_settings(args)
        # Lambda was chosen for the success score of the calibration's continuation: the same one.
        if args.continuation is not None and args.continuation != calibrated["continuation"]:
            raise EnergyMarginError(
                f"--calibration chose lambda with --continuation {int(calibrated['continuation'])}: "
                f"leave --continuation out or give the same, not {args.continuation}"
            )
        continuation = int(calibrated.pop("continuation"))
        chosen.update(calibrated)
    check_engine_device(args.engine, args.device)
    return AnalyzerConfig(
        expansions=expansions,
        nodes=args.nodes,
        cost=args.cost,
        likelihood_lambda=chosen["likelihood_lambda"],
        wrench_scale=chosen["wrench_scale"],
        duration_scale=chosen["duration_scale"],
        engine=args.engine,
        device=args.device,
        method=args.method,
        batch=args.batch,
        threads=args.threads,
        projection=args.projection,
        converge=args.converge,
        converge_rule=args.converge_rule,
        contacts=args.contacts,
        analysis_model=args.analysis_model,
        continuation=continuation,
        continuation_horizon=args.continuation_horizon,
        capture_gate=args.capture_gate,
    )


def tree_options_given(args: argparse.Namespace) -> list[str]:
    """The tree options of ``args`` that differ from their defaults, as ``--flag VALUE``."""
    parser = argparse.ArgumentParser(add_help=False)
    add_arguments(parser)
    given = []
    for dest, flag in TREE_ONLY.items():
        default = parser.get_default(dest)
        value = getattr(args, dest, default)
        if value != default:
            given.append(f"{flag} {value}")
    return given


def lambda_note(dataset: Dataset, config: AnalyzerConfig) -> str | None:
    """The one-line note for an analysis at a lambda nobody chose (:func:`~energy_margin.analysis.run.unchosen_lambda`).

    It says how to calibrate; ``None`` when ``config`` or the dataset's task sets lambda.
    """
    from energy_margin.analysis.run import unchosen_lambda

    origin = unchosen_lambda(dataset, config)
    if origin is None:
        return None
    task = dataset.task
    return (
        f"note: lambda is unset and uncalibrated: {task.label} gives no perturbation.lambda, so the scores use "
        f"the {origin} {task.config.likelihood_lambda:.3g} 1/J; to calibrate it on labelled data: "
        f"energy-margin calibrate {dataset.path} --out CAL, then energy-margin analyze DATASET "
        "--calibration CAL/calibration.json"
    )


def run(args: argparse.Namespace) -> int:
    """Analyse the dataset and print where the scores went."""
    if getattr(args, "model", None) is not None:
        return run_learned(args)
    from energy_margin.analysis.run import analyze_dataset, resolved_continuation
    from energy_margin.data.provenance import dataset_note
    from energy_margin.data.validation import require_valid

    config = analyzer_config(args)
    say_notes(dataset_note(args.dataset, engine=args.engine))
    dataset = require_valid(args.dataset, overlaps=True, scores=False)
    path = analyze_dataset(
        dataset,
        config,
        seed=args.seed,
        workers=args.workers,
        executor=args.executor,
        address=args.address,
        overwrite=args.overwrite,
        progress=not args.no_progress,
    )
    from energy_margin.data.scores_file import UNREACHED_SHARE, load_scores, rejection_note, unreached_success_share

    if Path(path).is_file():
        scores = load_scores(Path(path).parent)
        say_notes(rejection_note(scores))
        recorded = read_json(Path(path).parent / CONFIG_FILE, what="analysis settings")
        unreached = unreached_success_share(scores) if not resolved_continuation(recorded) else None
        if unreached is not None and unreached >= UNREACHED_SHARE:
            say_notes(
                f"note: {100 * unreached:.0f}% of the first-half frames score success 0: their trees end before the "
                "motion reaches the success region, so early success is not ranked; --continuation 16 continues the "
                "motion from each tree to its end (docs/howto/scenes.md, 'Success beyond a tree's reach')"
            )
    # After the analysis, so that a refused one says only why.
    say_notes(lambda_note(dataset, config))
    print(f"wrote {path}")
    return 0


def run_learned(args: argparse.Namespace) -> int:
    """Score the dataset with the learned margin of ``--model`` and print where the scores went."""
    given = tree_options_given(args)
    if given:
        raise EnergyMarginError(
            f"--model scores frames with a learned margin and grows no tree: {', '.join(given)} "
            f"{'does' if len(given) == 1 else 'do'} not apply"
        )
    from energy_margin.data.provenance import dataset_note
    from energy_margin.learning.scoring import score_dataset

    say_notes(dataset_note(args.dataset))
    path = score_dataset(
        args.dataset, args.model, overwrite=args.overwrite, progress=not args.no_progress, seed=args.seed
    )
    print(f"wrote {path}")
    return 0
