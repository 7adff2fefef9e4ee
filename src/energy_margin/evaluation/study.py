"""The study: one resumable command that measures the informative questions with intervals that tell methods apart.

For every task, :func:`run_study` generates a dataset (``OUT/<task>/dataset``), analyses it with
every tree method at every budget (``OUT/<task>/runs/<method>-<budget>/``, through
:func:`energy_margin.evaluation.budget.analyze_configuration`, so every configuration has its own
journal and resumes), and answers six questions with 95 % bootstrap intervals over trajectories:
capture at k-hat = 0, 2 and 4, and trajectory success predicted from the first 3 frames, the first
5 and the last 3 (each the weighted last ``success_frames`` = 3 frame scores of that span). Beside
the tree methods stand the ``current_state``, ``distance`` and ``chance`` (a constant score: AP =
positive rate) baselines. Differences (EST minus every other tree method at the same budget, EST
minus ``distance``) get **paired** intervals: the same resampled trajectories score both sides, and
the interval is the 2.5-97.5 percentile of the per-resample differences.

The likelihood lambda is swept by re-scoring, not regrowing: a tree does not depend on lambda (its
growth never reads it unless the adaptive budget ``converge`` is on), so every frame's tree is grown
once (``lambda_method`` at ``lambda_budget``) and scored with every lambda of the grid. Each lambda
gets a directory ``OUT/<task>/lambda/<method>-<budget>-lambda-<value>/`` whose ``analysis.json`` and
``scores.csv`` are exactly those ``analyze`` would write at that lambda (so ``analyze`` there finds
them finished), with one journal per lambda, so the sweep resumes too.

Outputs (rewritten as configurations finish): ``OUT/study.csv`` (AP with intervals),
``OUT/study_differences.csv``, ``OUT/study_lambda.csv``, ``OUT/study.json`` (all of them with the
settings and positive rates) and, with matplotlib, ``OUT/study_<task>.png`` and
``OUT/study_lambda_<task>.png``; the same files of one task alone in ``OUT/<task>/``, so studies of
different tasks (or budgets) in one ``OUT`` keep each task's latest tables.
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import functools
import io
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.analysis.executors import LocalExecutor
from energy_margin.analysis.frame import AnalyzerConfig, FrameAnalyzer, score_field
from energy_margin.analysis.run import open_analysis, run_description, write_scores
from energy_margin.data.dataset import Dataset, load_dataset
from energy_margin.data.generate import generate_dataset
from energy_margin.data.scores_file import load_scores, scores_journal
from energy_margin.data.validation import require_valid
from energy_margin.errors import EnergyMarginError
from energy_margin.evaluation.budget import (
    Questions,
    analyze_configuration,
    baseline_grids,
    bootstrap_answers,
    copy_dataset,
    cost_summary,
    format_table,
    percentile_interval,
    plot,
)
from energy_margin.evaluation.metrics import score_grid
from energy_margin.planning.methods import METHODS
from energy_margin.runs import progress_bar
from energy_margin.runs.files import atomic_write_text, write_json
from energy_margin.tasks import PushingTask, ScoopingTask


@dataclass(frozen=True)
class StudyTask:
    """The dataset of one task in the study.

    Attributes:
        objects: objects per scene n_o.
        seed: generation seed of its dataset.

    """

    objects: int
    seed: int


#: The study's tasks, each with its typical objects per scene, and datasets (seed 0 gives positive
#: rates in [0.2, 0.8] for every question at 100 trajectories x 10 frames: docs/evidence.md).
TASKS: dict[str, StudyTask] = {
    task.name: StudyTask(objects=task.typical_objects, seed=0) for task in (PushingTask, ScoopingTask)
}
DEFAULT_BUDGETS = (30, 100, 300)
#: Capture questions: name -> k-hat.
CAPTURE_WINDOWS = {"capture_k0": 0, "capture_k2": 2, "capture_k4": 4}
#: Success questions: name -> frame span whose weighted last 3 frames score the trajectory.
SUCCESS_SPANS: dict[str, tuple[int | None, int | None]] = {
    "success_first3": (0, 3),
    "success_first5": (0, 5),
    "success_last3": (None, None),
}
QUESTION_NAMES: tuple[str, ...] = (*CAPTURE_WINDOWS, *SUCCESS_SPANS)
LABELS = {
    "capture_k0": "capture, k-hat = 0",
    "capture_k2": "capture, k-hat = 2",
    "capture_k4": "capture, k-hat = 4",
    "success_first3": "success from first 3 frames",
    "success_first5": "success from first 5 frames",
    "success_last3": "success from last 3 frames",
}
HEADERS = ("capture k=0", "capture k=2", "capture k=4", "success first 3", "success first 5", "success last 3")
BASELINES = ("current_state", "distance", "chance")
#: The lambda grid relative to the task's lambda: 10^(k/2) for k = -6 .. 6.
LAMBDA_FACTORS = tuple(float(10.0 ** (k / 2)) for k in range(-6, 7))
_INTERVALS = tuple(f"{q}{suffix}" for q in QUESTION_NAMES for suffix in ("", "_low", "_high"))
FIELDS = ("task", "method", "budget", *_INTERVALS, "runtime_per_frame_s", "nodes_per_frame", "frames")
DIFFERENCE_FIELDS = ("task", "comparison", "budget", *_INTERVALS)
LAMBDA_FIELDS = ("task", "method", "budget", "lambda", "factor", *_INTERVALS)


def study_questions(dataset: Dataset) -> Questions:
    """The six questions of the study on ``dataset``."""
    return Questions(dataset, 3, capture_windows=CAPTURE_WINDOWS, success_spans=SUCCESS_SPANS)


def positive_rates(dataset: Dataset) -> dict[str, float]:
    """Fraction of positive labels of each question: frames for capture, trajectories for success."""
    rates = {name: float(dataset.capture_labels(window).mean()) for name, window in CAPTURE_WINDOWS.items()}
    rates["success"] = float(dataset.success_labels().mean())
    return rates


@dataclass
class Scored:
    """The answers of one scorer on one dataset.

    Attributes:
        point: AP of each question on all trajectories (``None``: one class).
        samples: AP of each question on every resample, shape (n_resamples,), NaN where undefined.

    """

    point: dict[str, float | None]
    samples: dict[str, np.ndarray]

    def row(self) -> dict[str, float | None]:
        """Point estimates and 95 % percentile intervals."""
        result: dict[str, float | None] = {}
        for name, value in self.point.items():
            result[name] = value
            result[f"{name}_low"], result[f"{name}_high"] = percentile_interval(self.samples[name])
        return result


def score_questions(questions: Questions, capture: np.ndarray, success: np.ndarray, resamples: np.ndarray) -> Scored:
    """AP of grids ``capture`` and ``success`` (each (T, K)) on all trajectories and on every resample (n, T)."""
    point = questions.answer(capture, success, np.arange(capture.shape[0]))
    return Scored(point, bootstrap_answers(questions, capture, success, resamples))


def paired_difference(first: Scored, second: Scored) -> dict[str, float | None]:
    """``first`` minus ``second`` with a paired 95 % interval (both scored on the same resamples).

    The point is the difference of the APs on all trajectories; the interval is the 2.5-97.5
    percentile of the per-resample differences (resamples where either is undefined are skipped).
    Identical scorers give exactly [0, 0].
    """
    result: dict[str, float | None] = {}
    for name, value in first.point.items():
        other = second.point[name]
        result[name] = None if value is None or other is None else value - other
        low, high = percentile_interval(first.samples[name] - second.samples[name])
        result[f"{name}_low"], result[f"{name}_high"] = low, high
    return result


class LambdaRescorer(FrameAnalyzer):
    """Grows each frame's tree once and scores it with every lambda of a grid.

    The result of a frame index is ``{"trajectory", "frame", "rows"}``, ``rows`` holding one scores
    row per lambda (in the grid's order), each what :class:`FrameAnalyzer` gives at that lambda.
    """

    def __init__(self, dataset: Dataset, config: AnalyzerConfig, seed: int, *, lambdas: Sequence[float]) -> None:
        super().__init__(dataset, config, seed)
        self.lambdas = tuple(float(lam) for lam in lambdas)

    def __call__(self, index: int) -> dict[str, Any]:
        """Rows of frame ``index`` at every lambda."""
        row, field = self.analyse(index)
        frame = self.dataset.frame(row["trajectory"], row["frame"])
        rows = []
        for lam in self.lambdas:
            capture, success = score_field(self.task, frame, field, lam)
            rows.append({**row, "capture_score": capture, "success_score": success})
        return {"trajectory": row["trajectory"], "frame": row["frame"], "rows": rows}


def lambda_directory(root: Path, method: str, budget: int, lam: float) -> Path:
    """Directory of the lambda ``lam`` re-scoring of ``method`` at ``budget`` under ``root``."""
    return root / f"{method}-{budget}-lambda-{lam:.6g}"


def rescore_lambdas(
    directory: Path | str,
    root: Path | str,
    lambdas: Sequence[float],
    *,
    config: AnalyzerConfig,
    seed: int = 0,
    workers: int = 1,
    progress: bool = True,
    directories: dict[float, Path] | None = None,
) -> dict[float, dict[str, np.ndarray]]:
    """Grow every frame's tree of the dataset ``directory`` once and score it with each of ``lambdas``.

    Each lambda's scores go to :func:`lambda_directory` under ``root`` (a copy of the dataset with
    the ``analysis.json``, journal and ``scores.csv`` that ``analyze`` writes at that lambda); an
    interrupted run resumes, regrowing only frames missing from some lambda's journal.

    Args:
        directory: dataset directory.
        root: where the per-lambda directories go.
        lambdas: inverse temperatures, 1/J, each finite and >= 0, distinct.
        config: analysis settings of the trees (its ``likelihood_lambda`` is ignored); ``converge``
            must be ``None`` (an adaptive budget makes the tree depend on lambda).
        seed: analysis seed.
        workers: local worker processes.
        progress: show a per-frame progress bar.
        directories: output directories of some lambdas instead of :func:`lambda_directory`. The
            task's own lambda is recorded as ``analyze`` with its default lambda records it, so its
            directory can be the run of that very configuration.

    Returns:
        Scores columns by lambda.

    """
    values = [float(lam) for lam in lambdas]
    if not values or any(not np.isfinite(lam) or lam < 0 for lam in values) or len(set(values)) != len(values):
        raise EnergyMarginError(f"lambdas must be distinct finite values >= 0, got {list(lambdas)!r}")
    if config.converge is not None:
        raise EnergyMarginError("re-scoring lambda needs trees that do not depend on it: converge must be off")
    source, root = Path(directory), Path(root)
    dirs = {lam: lambda_directory(root, config.method, int(config.iterations or 0), lam) for lam in values}
    dirs.update({float(lam): Path(path) for lam, path in (directories or {}).items() if float(lam) in dirs})
    open_rows: dict[float, dict[tuple[int, int], dict[str, Any]]] = {}
    dataset: Dataset | None = None
    with contextlib.ExitStack() as stack:
        for lam, work in dirs.items():
            copy_dataset(source, work)
            dataset = dataset if dataset is not None else require_valid(work, overlaps=True, scores=False)
            own = lam == dataset.task.config.likelihood_lambda
            description = run_description(
                dataset, dataclasses.replace(config, likelihood_lambda=None if own else lam), seed
            )
            run, done = open_analysis(work, description, dataset, overwrite=False)
            stack.enter_context(run)
            if done is not None:
                open_rows[lam] = done
        assert dataset is not None
        if open_rows:
            n_frames = dataset.n_frames
            total = dataset.n_trajectories * n_frames
            pending = [i for i in range(total) if any(divmod(i, n_frames) not in done for done in open_rows.values())]
            factory = functools.partial(LambdaRescorer, lambdas=values)
            bar = progress_bar(total, desc="lambda", initial=total - len(pending), enabled=progress)
            try:
                journals = {lam: stack.enter_context(scores_journal(dirs[lam])) for lam in open_rows}
                for result in LocalExecutor(workers, analyzer=factory).run(dataset, config, seed, pending):
                    key = (result["trajectory"], result["frame"])
                    for lam, row in zip(values, result["rows"], strict=True):
                        if lam in open_rows and key not in open_rows[lam]:
                            journals[lam].append(row)
                            open_rows[lam][key] = row
                    bar.update(1)
            finally:
                bar.close()
            for lam, done in open_rows.items():
                write_scores(dirs[lam], done)
    return {lam: load_scores(work) for lam, work in dirs.items()}


def _study_dataset(out: Path, task: str, spec: StudyTask, *, trajectories: int, frames: int) -> Dataset:
    directory = out / task / "dataset"
    if directory.exists():
        dataset = load_dataset(directory)
        found = (dataset.metadata["task"], dataset.n_objects, dataset.n_trajectories, dataset.n_frames)
        expected = (task, spec.objects, trajectories, frames)
        if found != expected or dataset.metadata.get("seed") != spec.seed:
            raise EnergyMarginError(
                f"{directory} holds another dataset (task, objects, trajectories, frames = {found}, "
                f"seed {dataset.metadata.get('seed')}); the study asks for {expected}, seed {spec.seed}: "
                "use another output directory"
            )
        return dataset
    return generate_dataset(
        task, n_objects=spec.objects, n_trajectories=trajectories, n_frames=frames, seed=spec.seed, out=directory
    )


def _write_csv(path: Path, rows: list[dict[str, Any]], fields: Sequence[str]) -> None:
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=list(fields), lineterminator="\n", extrasaction="ignore")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: "" if row.get(k) is None else row[k] for k in fields})
    atomic_write_text(path, buffer.getvalue())


@dataclass
class StudyResult:
    """The study's rows (as written to its files).

    Attributes:
        rows: AP with intervals per task and scorer (tree method at a budget, or baseline).
        differences: paired differences per task, comparison and budget.
        lambdas: AP with intervals per task and lambda.
        meta: settings, positive rates and dataset seeds.

    """

    rows: list[dict[str, Any]] = dataclasses.field(default_factory=list)
    differences: list[dict[str, Any]] = dataclasses.field(default_factory=list)
    lambdas: list[dict[str, Any]] = dataclasses.field(default_factory=list)
    meta: dict[str, Any] = dataclasses.field(default_factory=dict)

    def write(self, out: Path) -> list[Path]:
        """Write the tables of every task under ``out`` and each task's own under ``out/<task>``; their paths.

        A later study of other tasks or budgets in the same ``out`` rewrites ``out/study*`` but
        leaves the per-task tables of tasks it did not run.
        """
        paths = self._write(out, self)
        for task in dict.fromkeys(row["task"] for row in self.rows):
            mine = StudyResult(
                [r for r in self.rows if r["task"] == task],
                [r for r in self.differences if r["task"] == task],
                [r for r in self.lambdas if r["task"] == task],
                {**self.meta, "tasks": {task: self.meta.get("tasks", {}).get(task)}},
            )
            paths += self._write(out / task, mine)
        return paths

    @staticmethod
    def _write(out: Path, result: StudyResult) -> list[Path]:
        paths = [out / "study.csv", out / "study_differences.csv", out / "study_lambda.csv", out / "study.json"]
        _write_csv(paths[0], result.rows, FIELDS)
        _write_csv(paths[1], result.differences, DIFFERENCE_FIELDS)
        _write_csv(paths[2], result.lambdas, LAMBDA_FIELDS)
        rows = {"rows": result.rows, "differences": result.differences, "lambdas": result.lambdas}
        write_json(paths[3], {**result.meta, **rows})
        return paths


def run_study(
    out: Path | str,
    *,
    tasks: Sequence[str] = tuple(TASKS),
    trajectories: int = 100,
    frames: int = 10,
    budgets: Sequence[int] = DEFAULT_BUDGETS,
    methods: Sequence[str] = METHODS,
    lambdas: Sequence[float] | None = None,
    lambda_method: str = "est",
    lambda_budget: int = 100,
    seed: int = 0,
    workers: int = 1,
    bootstrap: int = 1000,
    task_specs: dict[str, StudyTask] | None = None,
    progress: bool = True,
    log: Callable[[str], None] | None = None,
) -> StudyResult:
    """Run (or resume) the study under ``out`` and write its tables and figures.

    Args:
        out: output directory (created).
        tasks: tasks to study, keys of ``task_specs``.
        trajectories: trajectories per dataset, >= 2.
        frames: frames per trajectory, >= 1.
        budgets: expansions per frame, each >= 1.
        methods: tree methods.
        lambdas: the lambda grid, 1/J, for every task (``None``: the task's lambda times
            :data:`LAMBDA_FACTORS`); an empty sequence skips the sweep.
        lambda_method: tree method of the lambda sweep.
        lambda_budget: expansions per frame of the lambda sweep, >= 1.
        seed: analysis seed (the same per-frame seeds for every configuration) and bootstrap seed.
        workers: local worker processes of every analysis.
        bootstrap: trajectory resamples of every interval, >= 1.
        task_specs: objects and generation seed per task (default :data:`TASKS`).
        progress: per-frame progress bars on standard error.
        log: receives one line per finished step (standard error by default).

    Returns:
        The rows written to ``out``.

    """
    specs = task_specs if task_specs is not None else TASKS
    _check_arguments(specs, tasks, trajectories, frames, budgets, methods, lambda_method, lambda_budget, seed)
    if isinstance(bootstrap, bool) or not isinstance(bootstrap, int) or bootstrap < 1:
        raise EnergyMarginError(f"bootstrap must be an integer >= 1, got {bootstrap!r}")
    say = log if log is not None else (lambda line: print(line, file=sys.stderr, flush=True))
    out_path = Path(out)
    out_path.mkdir(parents=True, exist_ok=True)
    result = StudyResult(
        meta={
            "trajectories": trajectories,
            "frames": frames,
            "budgets": list(budgets),
            "methods": list(methods),
            "seed": seed,
            "bootstrap": bootstrap,
            "workers": workers,
            "lambda_method": lambda_method,
            "lambda_budget": lambda_budget,
            "tasks": {},
        }
    )
    base = AnalyzerConfig()
    states = {
        task: _TaskState.open(out_path, task, specs[task], trajectories, frames, seed, bootstrap) for task in tasks
    }
    for task, state in states.items():
        result.meta["tasks"][task] = state.meta
        rates_text = ", ".join(f"{k} {v:.2f}" for k, v in state.rates.items())
        say(f"study {task}: dataset {state.directory}; positive rates {rates_text}")
        outside = [k for k, v in state.rates.items() if not 0.2 <= v <= 0.8]
        if outside:
            say(f"study {task}: positive rate outside [0.2, 0.8] for {', '.join(outside)}")
        for name, scored in state.scored.items():
            result.rows.append({"task": task, "method": name[0], "budget": 0, **scored.row(), "frames": 0})
    # Budget by budget (every task and method at one budget before the next), so an interrupted
    # study has answered the cheaper questions for every task first.
    total = len(tasks) * len(methods) * len(budgets)
    number = 0
    for budget in budgets:
        for task, state in states.items():
            for method in methods:
                number += 1
                started = time.perf_counter()
                work = out_path / task / "runs" / f"{method}-{budget}"
                if (method, budget) == (lambda_method, lambda_budget):
                    _lambda_sweep(result, state, lambdas, base, work, seed=seed, workers=workers, progress=progress)
                    say(f"study {task}: lambda sweep ({time.perf_counter() - started:.0f} s)")
                scores = analyze_configuration(
                    state.directory,
                    work,
                    base,
                    method=method,
                    budget=budget,
                    seed=seed,
                    workers=workers,
                    progress=progress,
                )
                scored = state.score(scores)
                state.scored[(method, budget)] = scored
                row: dict[str, Any] = {"task": task, "method": method, "budget": budget, **scored.row()}
                result.rows.append({**row, **cost_summary(scores)})
                _collect_differences(result, states, methods, budgets)
                result.write(out_path)
                say(
                    f"study [{number}/{total}] {task} {method} {budget}: "
                    + ", ".join(f"{q} {_fmt(row[q])}" for q in QUESTION_NAMES)
                    + f" ({time.perf_counter() - started:.0f} s)"
                )
        _plot_all(result, states, out_path, trajectories, frames)
    for task, state in states.items():
        if lambda_budget not in budgets or lambda_method not in methods:
            started = time.perf_counter()
            _lambda_sweep(result, state, lambdas, base, None, seed=seed, workers=workers, progress=progress)
            say(f"study {task}: lambda sweep ({time.perf_counter() - started:.0f} s)")
    _collect_differences(result, states, methods, budgets)
    result.write(out_path)
    _plot_all(result, states, out_path, trajectories, frames)
    return result


@dataclass
class _TaskState:
    """One task's dataset, questions, resamples and the answers so far."""

    task: str
    directory: Path
    dataset: Dataset
    questions: Questions
    resamples: np.ndarray
    rates: dict[str, float]
    meta: dict[str, Any]
    scored: dict[tuple[str, int], Scored]
    lambda_differences: list[dict[str, Any]] = dataclasses.field(default_factory=list)

    @classmethod
    def open(
        cls, out: Path, task: str, spec: StudyTask, trajectories: int, frames: int, seed: int, bootstrap: int
    ) -> _TaskState:
        dataset = _study_dataset(out, task, spec, trajectories=trajectories, frames=frames)
        rates = positive_rates(dataset)
        meta = {
            "objects": dataset.n_objects,
            "dataset_seed": spec.seed,
            "positive_rates": rates,
            "likelihood_lambda": dataset.task.config.likelihood_lambda,
        }
        questions = study_questions(dataset)
        resamples = np.random.default_rng(seed).integers(0, trajectories, (bootstrap, trajectories))
        state = cls(task, out / task / "dataset", dataset, questions, resamples, rates, meta, {})
        grids = dict(baseline_grids(dataset))
        constant = np.full(dataset.arrays["captured"].shape, 0.5)
        grids["chance"] = (constant, constant)
        for name in BASELINES:
            if name in grids:
                state.scored[(name, 0)] = score_questions(questions, *grids[name], resamples)
        return state

    def score(self, scores: dict[str, np.ndarray]) -> Scored:
        capture = score_grid(self.dataset, scores, "capture_score")
        success = score_grid(self.dataset, scores, "success_score")
        return score_questions(self.questions, capture, success, self.resamples)


def _lambda_sweep(
    result: StudyResult,
    state: _TaskState,
    lambdas: Sequence[float] | None,
    base: AnalyzerConfig,
    task_lambda_directory: Path | None,
    *,
    seed: int,
    workers: int,
    progress: bool,
) -> None:
    """Grow the trees of the lambda configuration (``result.meta``) once and score them at every lambda.

    The task's own lambda (in the default grid) writes to ``task_lambda_directory`` when given: the
    study's run of that configuration, which then needs no trees of its own.
    """
    lam = float(state.meta["likelihood_lambda"])
    values = [lam * f for f in LAMBDA_FACTORS] if lambdas is None else [float(v) for v in lambdas]
    if not values:
        return
    method, budget = result.meta["lambda_method"], result.meta["lambda_budget"]
    config = dataclasses.replace(base, method=method, iterations=budget, nodes=None)
    by_lambda = rescore_lambdas(
        state.directory,
        result_root(state.directory),
        values,
        config=config,
        seed=seed,
        workers=workers,
        progress=progress,
        directories={lam: task_lambda_directory} if task_lambda_directory is not None else None,
    )
    answers = {value: state.score(scores) for value, scores in by_lambda.items()}
    for value, scored in answers.items():
        row = {"task": state.task, "method": method, "budget": budget, "lambda": value}
        row["factor"] = value / lam if lam > 0 else None
        result.lambdas.append({**row, **scored.row()})
    # Every lambda against the task's own, paired on the same resamples (the same trees too).
    if lam in answers:
        state.lambda_differences = [
            {
                "task": state.task,
                "comparison": f"{method} lambda {value:.4g} - lambda {lam:.4g}",
                "budget": budget,
                **paired_difference(scored, answers[lam]),
            }
            for value, scored in answers.items()
            if value != lam
        ]


def result_root(directory: Path) -> Path:
    """Where the lambda directories of the dataset ``directory`` go: ``<task>/lambda`` beside it."""
    return directory.parent / "lambda"


def _plot_all(result: StudyResult, states: dict[str, _TaskState], out: Path, trajectories: int, frames: int) -> None:
    for task, state in states.items():
        title = f"{task}, n_o = {state.dataset.n_objects}, {trajectories} x {frames} frames"
        rows = [r for r in result.rows if r["task"] == task]
        lam = float(state.meta["likelihood_lambda"])
        for folder in (out, out / task):
            plot(rows, folder / f"study_{task}.png", title=title, questions=QUESTION_NAMES, labels=LABELS)
            lambdas = [r for r in result.lambdas if r["task"] == task]
            plot_lambda(lambdas, folder / f"study_lambda_{task}.png", lam, title)


def _collect_differences(
    result: StudyResult, states: dict[str, _TaskState], methods: Sequence[str], budgets: Sequence[int]
) -> None:
    result.differences = [
        row
        for name, state in states.items()
        for row in [*_differences(name, state.scored, methods, budgets), *state.lambda_differences]
    ]


def _differences(
    task: str, scored: dict[tuple[str, int], Scored], methods: Sequence[str], budgets: Sequence[int]
) -> list[dict[str, Any]]:
    rows: list[dict[str, Any]] = []
    if "est" not in methods:
        return rows
    for budget in budgets:
        if ("est", budget) not in scored:
            continue
        est = scored[("est", budget)]
        others = [(m, scored[(m, budget)]) for m in methods if m != "est" and (m, budget) in scored]
        if ("distance", 0) in scored:
            others.append(("distance", scored[("distance", 0)]))
        for name, other in others:
            rows.append(
                {"task": task, "comparison": f"est - {name}", "budget": budget, **paired_difference(est, other)}
            )
    return rows


def _check_arguments(
    specs: dict[str, StudyTask],
    tasks: Sequence[str],
    trajectories: int,
    frames: int,
    budgets: Sequence[int],
    methods: Sequence[str],
    lambda_method: str,
    lambda_budget: int,
    seed: int,
) -> None:
    def integer(value: object, least: int) -> bool:
        return not isinstance(value, bool) and isinstance(value, int) and value >= least

    unknown = [t for t in tasks if t not in specs]
    if not tasks or unknown or len(set(tasks)) != len(tasks):
        raise EnergyMarginError(f"tasks must be distinct names among {', '.join(specs)}, got {list(tasks)!r}")
    if not integer(trajectories, 2):
        raise EnergyMarginError(f"trajectories must be an integer >= 2, got {trajectories!r}")
    if not integer(frames, 1):
        raise EnergyMarginError(f"frames must be an integer >= 1, got {frames!r}")
    if not budgets or not all(integer(b, 1) for b in budgets) or len(set(budgets)) != len(budgets):
        raise EnergyMarginError(f"budgets must be distinct integers >= 1, got {list(budgets)!r}")
    bad = [m for m in methods if m not in METHODS]
    if not methods or bad or len(set(methods)) != len(methods):
        raise EnergyMarginError(f"methods must be distinct names among {', '.join(METHODS)}, got {list(methods)!r}")
    if lambda_method not in METHODS:
        raise EnergyMarginError(f"lambda method must be one of {', '.join(METHODS)}, got {lambda_method!r}")
    if not integer(lambda_budget, 1):
        raise EnergyMarginError(f"lambda budget must be an integer >= 1, got {lambda_budget!r}")
    if not integer(seed, 0):
        raise EnergyMarginError(f"seed must be a non-negative integer, got {seed!r}")


def plot_lambda(rows: list[dict[str, Any]], path: Path, default: float, title: str = "") -> Path | None:
    """AP of every question against lambda (log axis, intervals shaded, the task's lambda dashed).

    Args:
        rows: lambda rows of one task (``lambda`` and each question with ``_low``/``_high``).
        path: the PNG to write.
        default: the task's lambda, 1/J.
        title: figure title.

    Returns:
        ``path``, or ``None`` without matplotlib or without rows.

    """
    positive = [r for r in rows if r["lambda"] > 0]
    if not positive:
        return None
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    figure, axis = plt.subplots(figsize=(6.4, 4.2))
    values = [r["lambda"] for r in positive]
    for question in QUESTION_NAMES:
        points = [(v, r) for v, r in zip(values, positive, strict=True) if r.get(question) is not None]
        if not points:
            continue
        line = axis.plot([v for v, _ in points], [r[question] for _, r in points], marker="o", label=LABELS[question])
        low = [r[f"{question}_low"] for _, r in points]
        high = [r[f"{question}_high"] for _, r in points]
        if None not in low and None not in high:
            axis.fill_between([v for v, _ in points], low, high, color=line[0].get_color(), alpha=0.12)
    axis.axvline(default, linestyle="--", color="black", linewidth=1, label=f"task lambda = {default:g}")
    axis.set_xscale("log")
    axis.set_xlabel("lambda [1/J]")
    axis.set_ylabel("AP (95 % CI over trajectories)")
    axis.grid(True, alpha=0.3)
    axis.legend(fontsize=7, loc="lower left")
    if title:
        axis.set_title(title, fontsize=10)
    figure.tight_layout()
    figure.savefig(path, dpi=120)
    plt.close(figure)
    return path


def _fmt(value: float | None) -> str:
    return "n/a" if value is None else f"{value:.3f}"


def format_study(result: StudyResult) -> str:
    """The study's three tables as text: AP, paired differences, AP against lambda."""
    parts = [format_table(result.rows, questions=QUESTION_NAMES, headers=HEADERS, first=("task", "method"))]
    if result.differences:
        parts.append(
            "paired differences (same resamples):\n"
            + format_table(result.differences, questions=QUESTION_NAMES, headers=HEADERS, first=("task", "comparison"))
        )
    if result.lambdas:
        rows = [{**r, "lambda": f"{r['lambda']:.4g}"} for r in result.lambdas]
        parts.append(
            "AP against lambda:\n"
            + format_table(rows, questions=QUESTION_NAMES, headers=HEADERS, first=("task", "method", "lambda"))
        )
    return "\n\n".join(parts)
