"""The study: one resumable command that measures the informative questions with intervals that tell methods apart.

For every task, :func:`run_study` generates a dataset (``OUT/<task>/dataset``), analyses it with
every tree method at every budget (``OUT/<task>/runs/<method>-<budget>/``, through
:func:`energy_margin.experiments.budget.analyze_configuration`, so every configuration has its own
journal and resumes), and answers six questions with 95 % bootstrap intervals over trajectories:
capture at k-hat = 0, 2 and 4, and trajectory success predicted from the first 3 frames, the first
5 and the last 3 (each the weighted last ``success_frames`` = 3 frame scores of that span). Beside
the tree methods stand the ``current_state``, ``distance`` and ``chance`` (a constant score: AP =
positive rate) baselines. Differences (EST minus every other tree method at the same budget, EST
minus ``distance``) get **paired** intervals: the same resampled trajectories score both sides, and
the interval is the 2.5-97.5 percentile of the per-resample differences.

Lambda is swept by re-scoring (:mod:`energy_margin.evaluation.lambda_rescoring`): each tree grown
once (``lambda_method`` at ``lambda_budget``) is scored with every lambda of the grid, each in
``OUT/<task>/lambda/<method>-<budget>-lambda-<value>/``, exactly what ``analyze`` would write there.

``OUT`` is a run (:func:`energy_margin.runs.open_run`): ``OUT/study_settings.json`` is written
first and ``OUT`` stays locked while the study runs. The settings record, per task ever studied
in ``OUT``, what decides its datasets and analyses (objects, dataset seed, trajectories, frames,
analysis seed): a study of other tasks, budgets, methods or lambdas adds to ``OUT``, one that
changes a task's entry is refused unless ``overwrite``. The questions and the tables are in
:mod:`~energy_margin.experiments.study_result`, the figures in
:mod:`~energy_margin.experiments.study_display`.

Outputs (rewritten as configurations finish): ``OUT/study.csv`` (AP with intervals),
``OUT/study_differences.csv``, ``OUT/study_lambda.csv``, ``OUT/study.json`` (with the settings and
positive rates), with matplotlib ``OUT/study_<task>.png`` and ``OUT/study_lambda_<task>.png``; the
same files of each task alone in ``OUT/<task>/``, its latest tables.
"""

from __future__ import annotations

import dataclasses
import json
import sys
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from energy_margin._renamed import renamed_keyword
from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.errors import (
    EnergyMarginError,
    InvalidParameterError,
    check_choice,
    check_int,
    check_seed,
)
from energy_margin.evaluation.bootstrap import Scored, paired_difference, score_questions
from energy_margin.evaluation.lambda_rescoring import LambdaRescorer, lambda_directory, rescore_lambdas, result_root
from energy_margin.experiments.budget import analyze_configuration, cost_summary
from energy_margin.experiments.study_display import LambdaDisplay, draw_study, plot_lambda
from energy_margin.experiments.study_result import (
    BASELINES,
    CAPTURE_WINDOWS,
    DIFFERENCE_FIELDS,
    FIELDS,
    HEADERS,
    LABELS,
    LAMBDA_FACTORS,
    LAMBDA_FIELDS,
    QUESTION_NAMES,
    SUCCESS_SPANS,
    TABLE_FILES,
    StudyResult,
    format_study,
    method_differences,
    positive_rates,
    study_questions,
)
from energy_margin.experiments.study_state import TaskState
from energy_margin.planning.methods import METHODS
from energy_margin.runs import RunDirectory, RunSpec, open_run
from energy_margin.runs.files import read_json
from energy_margin.runs.progress import Progress
from energy_margin.runs.tables import fmt
from energy_margin.tasks import PushingTask, ScoopingTask

__all__ = [
    "BASELINES",
    "CAPTURE_WINDOWS",
    "DEFAULT_BUDGETS",
    "DIFFERENCE_FIELDS",
    "FIELDS",
    "HEADERS",
    "LABELS",
    "LAMBDA_FACTORS",
    "LAMBDA_FIELDS",
    "QUESTION_NAMES",
    "SETTINGS_FILE",
    "SUCCESS_SPANS",
    "TASKS",
    "LambdaDisplay",
    "LambdaRescorer",
    "Scored",
    "StudyResult",
    "StudyTask",
    "draw_study",
    "format_study",
    "lambda_directory",
    "paired_difference",
    "plot_lambda",
    "positive_rates",
    "rescore_lambdas",
    "result_root",
    "run_study",
    "score_questions",
    "study_questions",
    "study_run",
]


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
#: rates in [0.2, 0.8] for every question at 100 trajectories x 10 frames: docs/results/evidence.md).
TASKS: dict[str, StudyTask] = {
    task.name: StudyTask(objects=task.typical_objects, seed=0) for task in (PushingTask, ScoopingTask)
}
DEFAULT_BUDGETS = (30, 100, 300)
#: The study's settings file, written first in ``OUT``.
SETTINGS_FILE = "study_settings.json"


def study_run(tasks: Iterable[str], *, earlier_release: bool = False, studied: Iterable[str] = ()) -> RunSpec:
    """The run of a study in ``OUT`` whose outputs may concern ``tasks``.

    Only the entries of the tasks ``studied`` there before decide a different study (a new task adds
    its entry); ``overwrite`` removes the tables, figures and folders of ``tasks`` and the settings
    file. ``earlier_release``: ``OUT`` holds a study from before the settings file, which resumes.
    """
    names, before = list(dict.fromkeys(tasks)), set(studied)

    def studied_entries(settings: dict[str, Any], earlier: bool) -> dict[str, Any]:
        entries = settings.get("tasks")
        if not before or not isinstance(entries, dict):
            return settings
        return {**settings, "tasks": {t: e for t, e in entries.items() if t in before}}

    return RunSpec(
        contents="a study",
        settings_file=SETTINGS_FILE,
        outputs=(*TABLE_FILES, *(f for t in names for f in (f"study_{t}.png", f"study_lambda_{t}.png", t))),
        compared=("tasks",),
        shared_directory=earlier_release,
        normalize=studied_entries,
    )


def _open_study(out: Path, settings: dict[str, Any], known: Iterable[str], *, overwrite: bool) -> RunDirectory:
    """Open ``OUT`` for ``settings``, keeping the entries of the tasks studied there before."""
    settings_path = out / SETTINGS_FILE
    previous: dict[str, Any] = {}
    if settings_path.is_file():
        try:
            stored = read_json(settings_path, what="study settings")
        except EnergyMarginError:
            stored = None  # open_run refuses it (or overwrite replaces it)
        if isinstance(stored, dict) and isinstance(stored.get("tasks"), dict):
            previous = stored["tasks"]
    merged = {**settings, "tasks": {**previous, **settings["tasks"]}}
    earlier = not settings_path.exists() and (out / TABLE_FILES[3]).is_file()
    spec = study_run([*known, *previous], earlier_release=earlier, studied=previous)
    run = open_run(out, spec, merged, overwrite=overwrite)
    if not run.resumed and previous:
        # A replaced study keeps none of the tasks studied before.
        run.settings = json.loads(json.dumps(settings, sort_keys=True))
        run.write_settings()
    return run


def study_settings(
    specs: dict[str, StudyTask], tasks: Sequence[str], n_trajectories: int, n_frames: int, seed: int, **others: Any
) -> dict[str, Any]:
    """What ``study_settings.json`` records: each task's dataset and analysis seed, and the other settings.

    The file keeps the keys of release 0.2 (``trajectories``, ``frames``, ``budgets``,
    ``lambda_budget``), so a study written then resumes.
    """
    entries = {
        task: {
            "objects": specs[task].objects,
            "dataset_seed": specs[task].seed,
            "trajectories": n_trajectories,
            "frames": n_frames,
            "seed": seed,
        }
        for task in tasks
    }
    return {"tasks": entries, "trajectories": n_trajectories, "frames": n_frames, "seed": seed, **others}


@renamed_keyword(
    trajectories="n_trajectories", frames="n_frames", budgets="expansions", lambda_budget="lambda_expansions"
)
def run_study(
    out: Path | str,
    *,
    tasks: Sequence[str] = tuple(TASKS),
    n_trajectories: int = 100,
    n_frames: int = 10,
    expansions: Sequence[int] = DEFAULT_BUDGETS,
    methods: Sequence[str] = METHODS,
    lambdas: Sequence[float] | None = None,
    lambda_method: str = "est",
    lambda_expansions: int = 100,
    seed: int = 0,
    workers: int = 1,
    bootstrap: int = 1000,
    task_specs: dict[str, StudyTask] | None = None,
    overwrite: bool = False,
    progress: Progress = True,
    log: Callable[[str], None] | None = None,
) -> StudyResult:
    """Run (or resume) the study under ``out`` and write its tables and figures.

    Args:
        out: output directory (created), opened as a run: locked while the study runs, its
            settings (``study_settings.json``) written first.
        tasks: tasks to study, keys of ``task_specs``.
        n_trajectories: trajectories per dataset, >= 2.
        n_frames: frames per trajectory, >= 1.
        expansions: the budgets to compare, expansions per frame, each >= 1.
        methods: tree methods.
        lambdas: the lambda grid, 1/J, for every task (``None``: the task's lambda times
            :data:`LAMBDA_FACTORS`); an empty sequence skips the sweep.
        lambda_method: tree method of the lambda sweep.
        lambda_expansions: expansions per frame of the lambda sweep, >= 1.
        seed: analysis seed (the same per-frame seeds for every configuration) and bootstrap seed.
        workers: local worker processes of every analysis.
        bootstrap: trajectory resamples of every interval, >= 1.
        task_specs: objects and generation seed per task (default :data:`TASKS`).
        overwrite: replace a study in ``out`` whose datasets or analysis seed differ for one of
            ``tasks`` (every output of the study there) instead of refusing.
        progress: per-frame progress bars on standard error.
        log: receives one line per finished step (standard error by default).

    Returns:
        The rows written to ``out``.

    """
    specs = task_specs if task_specs is not None else TASKS
    _check_arguments(
        specs, tasks, n_trajectories, n_frames, expansions, methods, lambda_method, lambda_expansions, seed
    )
    check_int("bootstrap", bootstrap, minimum=1)
    check_int("workers", workers, minimum=1)
    say = log if log is not None else (lambda line: print(line, file=sys.stderr, flush=True))
    others = {"budgets": list(expansions), "methods": list(methods), "bootstrap": bootstrap, "workers": workers}
    others.update(lambdas=None if lambdas is None else list(lambdas), lambda_method=lambda_method)
    # The settings file keeps its keys: "budgets" and "lambda_budget" are the expansions per frame.
    settings = study_settings(specs, tasks, n_trajectories, n_frames, seed, lambda_budget=lambda_expansions, **others)
    out_path = Path(out)
    with _open_study(out_path, settings, specs, overwrite=overwrite):
        study = _Study.open(out_path, specs, settings, lambdas, say=say, progress=progress)
        study.run()
        draw_study(study.result, out_path)
    return study.result


@dataclass
class _Study:
    """A study under way: its settings, the tasks' states and the result so far."""

    out: Path
    settings: dict[str, Any]
    lambdas: Sequence[float] | None
    states: dict[str, TaskState]
    result: StudyResult
    say: Callable[[str], None]
    progress: Progress
    base: AnalyzerConfig = dataclasses.field(default_factory=AnalyzerConfig)

    @classmethod
    def open(
        cls,
        out: Path,
        specs: dict[str, StudyTask],
        settings: dict[str, Any],
        lambdas: Sequence[float] | None,
        *,
        say: Callable[[str], None],
        progress: Progress,
    ) -> _Study:
        """Open every task (its dataset generated or checked) and answer its baselines."""
        keys = ("trajectories", "frames", "budgets", "methods", "seed", "bootstrap", "workers")
        meta = {key: settings[key] for key in keys}
        meta.update(lambda_method=settings["lambda_method"], lambda_budget=settings["lambda_budget"], tasks={})
        result = StudyResult(meta=meta)
        tasks = list(settings["tasks"])
        states = {
            task: TaskState.open(
                out, task, specs[task], meta["trajectories"], meta["frames"], meta["seed"], meta["bootstrap"]
            )
            for task in tasks
        }
        for task, state in states.items():
            meta["tasks"][task] = state.meta
            rates_text = ", ".join(f"{k} {v:.2f}" for k, v in state.rates.items())
            say(f"study {task}: dataset {state.directory}; positive rates {rates_text}")
            outside = [k for k, v in state.rates.items() if not 0.2 <= v <= 0.8]
            if outside:
                say(f"study {task}: positive rate outside [0.2, 0.8] for {', '.join(outside)}")
            for name, scored in state.scored.items():
                result.rows.append({"task": task, "method": name[0], "budget": 0, **scored.row(), "frames": 0})
        return cls(out, settings, lambdas, states, result, say, progress)

    def run(self) -> None:
        """Every configuration, budget by budget, then the lambda sweeps not yet done; the tables kept written."""
        meta = self.result.meta
        # Budget by budget (every task and method at one budget before the next), so an interrupted
        # study has answered the cheaper questions for every task first.
        total = len(self.states) * len(meta["methods"]) * len(meta["budgets"])
        number = 0
        for budget in meta["budgets"]:
            for state in self.states.values():
                for method in meta["methods"]:
                    number += 1
                    self._configuration(state, method, budget, f"{number}/{total}")
        for task, state in self.states.items():
            if meta["lambda_budget"] not in meta["budgets"] or meta["lambda_method"] not in meta["methods"]:
                started = time.perf_counter()
                self._lambda_sweep(state, None)
                self.say(f"study {task}: lambda sweep ({time.perf_counter() - started:.0f} s)")
        self._collect_differences()
        self.result.write(self.out)

    def _configuration(self, state: TaskState, method: str, budget: int, number: str) -> None:
        meta, task = self.result.meta, state.task
        started = time.perf_counter()
        work = self.out / task / "runs" / f"{method}-{budget}"
        if (method, budget) == (meta["lambda_method"], meta["lambda_budget"]):
            self._lambda_sweep(state, work)
            self.say(f"study {task}: lambda sweep ({time.perf_counter() - started:.0f} s)")
        scores = analyze_configuration(
            state.directory,
            work,
            self.base.fixed_continuation(),
            method=method,
            budget=budget,
            seed=meta["seed"],
            workers=meta["workers"],
            progress=self.progress,
        )
        scored = state.score(scores)
        state.scored[(method, budget)] = scored
        row: dict[str, Any] = {"task": task, "method": method, "budget": budget, **scored.row()}
        self.result.rows.append({**row, **cost_summary(scores)})
        self._collect_differences()
        self.result.write(self.out)
        self.say(
            f"study [{number}] {task} {method} {budget}: "
            + ", ".join(f"{q} {fmt(row[q])}" for q in QUESTION_NAMES)
            + f" ({time.perf_counter() - started:.0f} s)"
        )

    def _lambda_sweep(self, state: TaskState, task_lambda_directory: Path | None) -> None:
        """Grow the trees of the lambda configuration once and score them at every lambda.

        The task's own lambda (in the default grid) writes to ``task_lambda_directory`` when given:
        the study's run of that configuration, which then needs no trees of its own.
        """
        lam = float(state.meta["likelihood_lambda"])
        values = [lam * f for f in LAMBDA_FACTORS] if self.lambdas is None else [float(v) for v in self.lambdas]
        if not values:
            return
        meta = self.result.meta
        method, budget = meta["lambda_method"], meta["lambda_budget"]
        by_lambda = rescore_lambdas(
            state.directory,
            result_root(state.directory),
            values,
            config=dataclasses.replace(self.base.fixed_continuation(), method=method, expansions=budget, nodes=None),
            seed=meta["seed"],
            workers=meta["workers"],
            progress=self.progress,
            directories={lam: task_lambda_directory} if task_lambda_directory is not None else None,
        )
        answers = {value: state.score(scores) for value, scores in by_lambda.items()}
        for value, scored in answers.items():
            row = {"task": state.task, "method": method, "budget": budget, "lambda": value}
            row["factor"] = value / lam if lam > 0 else None
            self.result.lambdas.append({**row, **scored.row()})
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

    def _collect_differences(self) -> None:
        methods, budgets = self.result.meta["methods"], self.result.meta["budgets"]
        self.result.differences = [
            row
            for name, state in self.states.items()
            for row in [*method_differences(name, state.scored, methods, budgets), *state.lambda_differences]
        ]


def _distinct(name: str, values: Sequence[Any], wanted: str) -> None:
    if not values or len(set(values)) != len(values):
        raise InvalidParameterError(name, f"must be distinct {wanted}, got {list(values)!r}")


def _check_arguments(
    specs: dict[str, StudyTask],
    tasks: Sequence[str],
    n_trajectories: int,
    n_frames: int,
    expansions: Sequence[int],
    methods: Sequence[str],
    lambda_method: str,
    lambda_expansions: int,
    seed: int,
) -> None:
    _distinct("tasks", tasks, f"names among {', '.join(specs)}")
    for task in tasks:
        check_choice("tasks", task, specs)
    check_int("n_trajectories", n_trajectories, minimum=2)
    check_int("n_frames", n_frames, minimum=1)
    for budget in expansions:
        check_int("expansions", budget, minimum=1)
    _distinct("expansions", expansions, "integers >= 1")
    for method in methods:
        check_choice("methods", method, METHODS)
    _distinct("methods", methods, f"names among {', '.join(METHODS)}")
    check_choice("lambda_method", lambda_method, METHODS)
    check_int("lambda_expansions", lambda_expansions, minimum=1)
    check_seed(seed)
