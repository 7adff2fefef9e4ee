"""``calibrate``: the likelihood lambda of a dataset chosen by cross-validated AP, nested by trajectory.

A tree does not depend on lambda, so every frame's tree is grown once and scored at every lambda
of a grid (:func:`~energy_margin.evaluation.lambda_rescoring.rescore_lambdas`, resumable, on
workers). The trajectories are split into K folds (``numpy.random.default_rng(seed)``). For each
fold, lambda is chosen on the other K - 1 folds (the highest mean AP over the objective's
questions; the smaller lambda of equals) and the fold is scored at that lambda: the held-out
scores of every trajectory come from a choice that never saw it, and their AP, with a paired
bootstrap interval against each baseline, is the figure to report. The lambda written for use on
new data is chosen on all trajectories.

With growth scales (``wrench_scales``, ``duration_scales``: factors on the task's perturbation
wrench bounds and longest propagation, which change the trees), every pair of scales grows its own
trees, each scored at every lambda, and the choice runs over every (scales, lambda) candidate the
same way.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.data.dataset import Dataset
from energy_margin.data.validation import require_valid
from energy_margin.errors import EnergyMarginError, check_int, check_positive_int, check_seed
from energy_margin.evaluation.baselines import baseline_grids
from energy_margin.evaluation.bootstrap import Questions
from energy_margin.evaluation.lambda_rescoring import rescore_lambdas
from energy_margin.evaluation.metrics import score_grid
from energy_margin.evaluation.verdict import verdicts
from energy_margin.runs import RunSpec, open_run
from energy_margin.runs.files import read_json
from energy_margin.runs.progress import Progress

__all__ = [
    "CALIBRATION_FILE",
    "CALIBRATION_RUN",
    "DEFAULT_LAMBDAS",
    "DEFAULT_OBJECTIVE",
    "FORMAT",
    "QUESTIONS",
    "Calibration",
    "Candidate",
    "calibrate",
    "check_calibration_data",
    "read_calibration",
]

#: The calibration file a run writes and ``analyze --calibration`` reads.
CALIBRATION_FILE = "calibration.json"
FORMAT = "energy-margin-calibration"
#: The lambda grid, 1/J: from a tenth to twenty times the paper's 5.
DEFAULT_LAMBDAS = (0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0)
#: The questions the choice maximises by default: those a frame cannot answer by itself.
DEFAULT_OBJECTIVE = ("capture_ap_window2", "success_ap_first_half")
QUESTIONS = ("capture_ap", "capture_ap_window2", "success_ap", "success_ap_first_half")

CALIBRATION_RUN = RunSpec(
    contents="a calibration", settings_file=CALIBRATION_FILE, outputs=("lambda",), settings_key="settings"
)


@dataclass(frozen=True)
class Calibration:
    """What :func:`calibrate` chose and measured.

    Attributes:
        task: the dataset's task.
        likelihood_lambda: the lambda chosen on all trajectories, 1/J (for use on new data).
        wrench_scale: the wrench-bound factor chosen with it (1 without growth scales).
        duration_scale: the propagation-length factor chosen with it (1 without growth scales).
        lambdas: the grid, 1/J.
        folds: per fold: its trajectories, the lambda chosen without them, and their AP at it.
        held_out: AP of the held-out scores per question (``None``: one class).
        default_lambda: the task's own lambda, 1/J, and ``default``: the AP at it per question.
        default: AP per question at the task's lambda.
        verdict: per question, the held-out scores against the best baseline (see
            :mod:`energy_margin.evaluation.verdict`), as dictionaries.
        baselines: AP per question of the current-state and distance baselines.
        objective: the questions whose mean AP the choice maximises.
        held_out_scores: the held-out capture and success scores, each (T, K): every trajectory
            scored at the candidate chosen without it (not written to ``calibration.json``).
        default_scores: the capture and success scores at the task's own settings, each (T, K)
            (not written either).
    """

    task: str
    likelihood_lambda: float
    lambdas: tuple[float, ...]
    folds: list[dict[str, Any]]
    held_out: dict[str, float | None]
    default_lambda: float
    default: dict[str, float | None]
    verdict: dict[str, dict[str, Any]]
    baselines: dict[str, dict[str, float | None]]
    objective: tuple[str, ...]
    wrench_scale: float = 1.0
    duration_scale: float = 1.0
    held_out_scores: tuple[np.ndarray, np.ndarray] | None = field(default=None, repr=False, compare=False)
    default_scores: tuple[np.ndarray, np.ndarray] | None = field(default=None, repr=False, compare=False)

    def settings(self) -> dict[str, float]:
        """The analysis settings chosen: ``likelihood_lambda``, ``wrench_scale``, ``duration_scale``."""
        return {
            "likelihood_lambda": self.likelihood_lambda,
            "wrench_scale": self.wrench_scale,
            "duration_scale": self.duration_scale,
        }

    def to_dict(self) -> dict[str, Any]:
        """JSON-compatible fields (the score grids left out)."""
        return {
            item.name: dataclasses.asdict(self)[item.name]
            for item in dataclasses.fields(self)
            if item.name not in ("held_out_scores", "default_scores")
        }


def _mean(values: dict[str, float | None], names: tuple[str, ...]) -> float:
    defined = [value for value in (values[name] for name in names) if value is not None]
    return float(np.mean(defined)) if defined else float("-inf")


def check_calibration_data(dataset: Dataset, *, folds: int, objective: tuple[str, ...]) -> None:
    """Refuse a dataset calibration cannot learn from, in one line.

    Raises:
        EnergyMarginError: fewer trajectories than folds, or an objective question whose labels
            are all one class.
    """
    if dataset.n_trajectories < folds:
        raise EnergyMarginError(
            f"calibrate needs at least {folds} trajectories for {folds} folds (`folds`); "
            f"{dataset.path} has {dataset.n_trajectories}"
        )
    labels = {
        "capture_ap": dataset.capture_labels(0),
        "capture_ap_window2": dataset.capture_labels(2),
        "success_ap": dataset.success_labels(),
        "success_ap_first_half": dataset.success_labels(),
    }
    for name in objective:
        values = np.asarray(labels[name], dtype=bool)
        if values.all() or not values.any():
            kind = "positive" if values.all() else "negative"
            raise EnergyMarginError(
                f"calibrate: every label of {name} in {dataset.path} is {kind}: AP is undefined, so nothing "
                "can be chosen by it (choose other questions with `objective`)"
            )


def calibrate(
    directory: Path | str,
    out: Path | str,
    *,
    lambdas: tuple[float, ...] = DEFAULT_LAMBDAS,
    folds: int = 5,
    objective: tuple[str, ...] = DEFAULT_OBJECTIVE,
    config: AnalyzerConfig | None = None,
    seed: int = 0,
    workers: int = 1,
    resamples: int = 1000,
    success_frames: int = 3,
    wrench_scales: tuple[float, ...] = (1.0,),
    duration_scales: tuple[float, ...] = (1.0,),
    progress: Progress = True,
    overwrite: bool = False,
) -> Calibration:
    """Choose lambda for the dataset ``directory`` by nested cross-validated AP; write ``out/calibration.json``.

    Args:
        directory: a dataset (its labels are what the choice is measured on).
        out: the run directory: the per-lambda scores (``lambda/``) and ``calibration.json``.
        lambdas: the grid, 1/J, each >= 0 (the task's own lambda is always added).
        folds: K, >= 2; the dataset needs at least K trajectories.
        objective: questions (of :data:`QUESTIONS`) whose mean AP the choice maximises.
        config: analysis settings of the trees (the default analysis when ``None``); its lambda is
            what is chosen, and ``converge`` must be off (a tree must not depend on lambda).
        seed: analysis seed, fold split and bootstrap resamples.
        workers: worker processes growing the trees.
        resamples: bootstrap resamples of the verdicts, >= 1.
        success_frames: k-bar of the success questions.
        wrench_scales: factors on the task's perturbation wrench bounds to choose among, each > 0
            (each pair of scales grows its own trees; 1 is always a candidate).
        duration_scales: factors on the task's longest perturbation propagation, each > 0.
        progress: show a progress bar while trees grow.
        overwrite: replace a calibration of other settings in ``out``.

    Returns:
        The :class:`Calibration` (also written to ``out/calibration.json``).
    """
    config = _checked_options(folds, seed, resamples, objective, config)
    dataset = require_valid(directory, overlaps=True, scores=False)
    check_calibration_data(dataset, folds=folds, objective=objective)
    grid, growth = _grid_and_growth(dataset, lambdas, wrench_scales, duration_scales)
    settings = {
        "format": FORMAT,
        "dataset": dataset.identity(),
        "analyzer": dataclasses.replace(config, likelihood_lambda=None).to_dict(),
        "lambdas": list(grid),
        "folds": folds,
        "objective": list(objective),
        "seed": seed,
        "resamples": resamples,
        "success_frames": success_frames,
        "growth": [list(pair) for pair in growth],
    }
    out = Path(out)
    with open_run(out, CALIBRATION_RUN, settings, overwrite=overwrite, engine=config.engine) as run:
        candidates = _candidate_scores(
            directory, out, grid, growth, config, seed=seed, workers=workers, progress=progress
        )
        result = _choose(
            dataset,
            candidates,
            grid,
            folds=folds,
            objective=objective,
            seed=seed,
            resamples=resamples,
            success_frames=success_frames,
        )
        run.write_settings({"result": result.to_dict()})
    return result


def _checked_options(
    folds: int, seed: int, resamples: int, objective: tuple[str, ...], config: AnalyzerConfig | None
) -> AnalyzerConfig:
    """The analysis settings (the default analysis when ``None``), once every option is checked."""
    check_int("folds", folds, minimum=2)
    check_seed(seed)
    check_positive_int("resamples", resamples)
    unknown = [name for name in objective if name not in QUESTIONS]
    if not objective or unknown:
        raise EnergyMarginError(f"objective must name questions of {', '.join(QUESTIONS)}, got {list(objective)}")
    config = config if config is not None else AnalyzerConfig()
    if config.converge is not None:
        raise EnergyMarginError("calibrate grows trees that do not depend on lambda: `converge` must be off")
    # Lambda is calibrated for one success score, stated: continuation None (analyze's rule) is 0 here.
    return config if config.continuation is not None else dataclasses.replace(config, continuation=0)


def _grid_and_growth(
    dataset: Dataset,
    lambdas: tuple[float, ...],
    wrench_scales: tuple[float, ...],
    duration_scales: tuple[float, ...],
) -> tuple[tuple[float, ...], list[tuple[float, float]]]:
    """The lambda grid (1/J, sorted, with the task's own) and the (wrench, duration) scales, (1, 1) first."""
    # The task's own lambda is always a candidate, so the calibration can keep it.
    grid = tuple(sorted({float(lam) for lam in lambdas} | {float(dataset.task.config.likelihood_lambda)}))
    for name, scales in (("wrench_scales", wrench_scales), ("duration_scales", duration_scales)):
        if not scales or any(not np.isfinite(value) or value <= 0 for value in scales):
            raise EnergyMarginError(f"{name} must be positive numbers, got {list(scales)}")
    others = {(float(w), float(d)) for w in wrench_scales for d in duration_scales} - {(1.0, 1.0)}
    return grid, [(1.0, 1.0), *sorted(others)]


def _candidate_scores(
    directory: Path | str,
    out: Path,
    grid: tuple[float, ...],
    growth: list[tuple[float, float]],
    config: AnalyzerConfig,
    *,
    seed: int,
    workers: int,
    progress: Progress,
) -> dict[tuple[float, float, float], dict[str, np.ndarray]]:
    """The scores of every (wrench scale, duration scale, lambda): one set of trees per pair of scales."""
    candidates: dict[tuple[float, float, float], dict[str, np.ndarray]] = {}
    for wrench, duration in growth:
        grown = dataclasses.replace(config, wrench_scale=wrench, duration_scale=duration)
        root = out / "lambda" if (wrench, duration) == (1.0, 1.0) else out / "lambda" / f"w{wrench:g}-d{duration:g}"
        scored = rescore_lambdas(directory, root, grid, config=grown, seed=seed, workers=workers, progress=progress)
        candidates.update({(wrench, duration, lam): scores for lam, scores in scored.items()})
    return candidates


Candidate = tuple[float, float, float]  # (wrench_scale, duration_scale, likelihood_lambda)


def _choose(
    dataset: Dataset,
    scored: dict[Candidate, dict[str, np.ndarray]],
    grid: tuple[float, ...],
    *,
    folds: int,
    objective: tuple[str, ...],
    seed: int,
    resamples: int,
    success_frames: int,
) -> Calibration:
    """The nested choice on score columns by candidate (in order: the task's own growth first, lambdas ascending)."""
    grids = {
        candidate: (score_grid(dataset, scores, "capture_score"), score_grid(dataset, scores, "success_score"))
        for candidate, scores in scored.items()
    }
    order_of = sorted(grids, key=lambda c: ((c[0], c[1]) != (1.0, 1.0), c[0], c[1], c[2]))
    questions = Questions.of_evaluate(dataset, success_frames=success_frames)
    order = np.random.default_rng(seed).permutation(dataset.n_trajectories)
    split = [np.sort(part) for part in np.array_split(order, folds)]

    def best(rows: np.ndarray) -> Candidate:
        # The highest mean AP; among equals the first in order: the task's own growth, the smaller lambda.
        means = [(_mean(questions.answer(*grids[c], rows), objective), -rank) for rank, c in enumerate(order_of)]
        return order_of[-max(means)[1]]

    first = grids[order_of[0]]
    held_capture, held_success = np.empty_like(first[0]), np.empty_like(first[1])
    fold_rows = []
    for held in split:
        train = np.setdiff1d(np.arange(dataset.n_trajectories), held)
        chosen = best(train)
        held_capture[held], held_success[held] = grids[chosen][0][held], grids[chosen][1][held]
        fold_rows.append(
            {
                "trajectories": held.tolist(),
                "likelihood_lambda": chosen[2],
                "wrench_scale": chosen[0],
                "duration_scale": chosen[1],
                "held_out": questions.answer(*grids[chosen], held),
                "train_objective": _mean(questions.answer(*grids[chosen], train), objective),
            }
        )
    everything = np.arange(dataset.n_trajectories)
    held_out = questions.answer(held_capture, held_success, everything)
    baselines_scores = baseline_grids(dataset)
    found = verdicts(
        dataset,
        (held_capture, held_success),
        baselines_scores,
        capture_window=0,
        success_frames=success_frames,
        weights="linear",
        resamples=resamples,
        seed=seed,
    )
    default_lambda = float(dataset.task.config.likelihood_lambda)
    chosen = best(everything)
    return Calibration(
        task=str(dataset.metadata["task"]),
        likelihood_lambda=chosen[2],
        lambdas=grid,
        folds=fold_rows,
        held_out=held_out,
        default_lambda=default_lambda,
        default=questions.answer(*grids[(1.0, 1.0, default_lambda)], everything),
        verdict={name: verdict.to_dict() for name, verdict in found.items()},
        baselines={name: questions.answer(*scores, everything) for name, scores in baselines_scores.items()},
        objective=objective,
        wrench_scale=chosen[0],
        duration_scale=chosen[1],
        held_out_scores=(held_capture, held_success),
        default_scores=grids[(1.0, 1.0, default_lambda)],
    )


def read_calibration(path: Path | str, *, task: str) -> dict[str, float]:
    """The analysis settings of a calibration file for a dataset of ``task``.

    Returns:
        ``likelihood_lambda`` (1/J), ``wrench_scale`` and ``duration_scale`` (1 in a file without
        growth scales), and ``continuation``, the success continuation lambda was chosen with (0
        in a file without one).

    Raises:
        EnergyMarginError: not a calibration file, an unfinished one, or one of another task.
    """
    path = Path(path)
    document = read_json(path, what=CALIBRATION_FILE)
    settings = document.get("settings") if isinstance(document, dict) else None
    result = document.get("result") if isinstance(document, dict) else None
    if not isinstance(settings, dict) or settings.get("format") != FORMAT:
        raise EnergyMarginError(f"{path} is not a calibration file (energy-margin calibrate writes one)")
    if not isinstance(result, dict) or not isinstance(result.get("likelihood_lambda"), int | float):
        raise EnergyMarginError(f"{path}: the calibration has not finished; run energy-margin calibrate again")
    if result.get("task") != task:
        raise EnergyMarginError(f"{path} calibrates task {result.get('task')!r}, not this dataset's {task!r}")
    chosen = {"likelihood_lambda": float(result["likelihood_lambda"])}
    for name in ("wrench_scale", "duration_scale"):
        value = result.get(name, 1.0)
        if isinstance(value, bool) or not isinstance(value, int | float) or not value > 0:
            raise EnergyMarginError(f"{path}: {name} must be a positive number, got {value!r}")
        chosen[name] = float(value)
    analyzer = settings.get("analyzer")
    continuation = analyzer.get("continuation", 0) if isinstance(analyzer, dict) else 0
    if isinstance(continuation, bool) or not isinstance(continuation, int) or continuation < 0:
        raise EnergyMarginError(f"{path}: analyzer.continuation must be a non-negative integer, got {continuation!r}")
    chosen["continuation"] = continuation
    return chosen
