"""AP against the expansion budget for every tree method, with bootstrap confidence intervals.

``budget_sweep`` analyses a dataset once per (method, budget) in its own working directory
``DIR/budget/<method>-<budget>/`` (a copy of the dataset files; ``DIR/scores.csv`` is never touched),
through :func:`energy_margin.analysis.run.analyze`, so every configuration writes its journal as frames
finish and an interrupted sweep resumes where it stopped. The work directory is a run
(:func:`energy_margin.runs.open_run`): ``budget_settings.json`` first, one writer at a time, one
resume rule and ``overwrite``. After each configuration the summary CSV and JSON are rewritten; the
figure (:class:`~energy_margin.experiments.budget_display.BudgetDisplay`, with matplotlib installed,
a PNG beside them) is drawn once the tables are written.

Questions: capture at k-hat = 0 and k-hat = 2, and trajectory success predicted from the first half
of the frames (the weighted last ``success_frames`` frames of that half, as ``evaluate``). The 95 %
confidence intervals resample whole trajectories with replacement (the same seeded resamples for
every row, so rows are paired); a resample whose labels hold a single class is skipped
(:mod:`energy_margin.evaluation.bootstrap`).
"""

from __future__ import annotations

import re
import sys
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin._renamed import renamed_keyword
from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.run import analyze
from energy_margin.data.dataset import Dataset, load_dataset
from energy_margin.data.dataset_files import copy_dataset
from energy_margin.data.scores_file import load_scores
from energy_margin.errors import EnergyMarginError, InvalidParameterError, check_choice, check_int, check_seed
from energy_margin.evaluation.baselines import baseline_grids
from energy_margin.evaluation.bootstrap import (
    Questions,
    average_precision,
    bootstrap_answers,
    percentile_interval,
    summarize,
)
from energy_margin.evaluation.metrics import score_grid
from energy_margin.experiments.budget_display import BudgetDisplay
from energy_margin.planning.methods import METHODS
from energy_margin.runs import RunSpec, run_directory, tables
from energy_margin.runs.progress import Progress
from energy_margin.runs.results import TypedResult
from energy_margin.runs.tables import Column, fmt, write_csv, write_json

__all__ = [
    "DEFAULT_BUDGETS",
    "FIELDS",
    "QUESTIONS",
    "QUESTION_LABELS",
    "BudgetSweepResult",
    "Questions",
    "analyze_configuration",
    "average_precision",
    "baseline_grids",
    "bootstrap_answers",
    "budget_run",
    "budget_sweep",
    "cost_summary",
    "format_table",
    "percentile_interval",
    "plot",
    "summarize",
    "sweep_settings",
]

DEFAULT_BUDGETS = (10, 30, 100, 300, 1000)
WORK_DIR = "budget"
QUESTIONS = ("capture_ap", "capture_ap_window2", "success_ap_first_half")
FIELDS = (
    "method",
    "budget",
    *(f"{q}{suffix}" for q in QUESTIONS for suffix in ("", "_low", "_high")),
    "runtime_per_frame_s",
    "nodes_per_frame",
    "frames",
)


#: Names of the questions in plots and tables.
QUESTION_LABELS = {
    "capture_ap": "capture, k-hat = 0",
    "capture_ap_window2": "capture, k-hat = 2",
    "success_ap_first_half": "success from first half",
}


#: The settings file of a sweep, written first in its work directory.
SETTINGS_FILE = "budget_settings.json"
_CONFIGURATION = re.compile(rf"^(?:{'|'.join(map(re.escape, METHODS))})-[0-9]+$")


@dataclass(frozen=True, kw_only=True)
class BudgetSweepResult(TypedResult):
    """What :func:`budget_sweep` measured; ``to_dict()`` is the summary JSON beside its CSV.

    Releases before 0.2 returned the list of rows: for one release ``result[i]`` still reads row
    ``i``, with a :class:`DeprecationWarning` (use ``result.rows[i]``).

    Attributes:
        dataset: the dataset's directory.
        task: its task's registered name.
        n_trajectories: its trajectories.
        n_frames: its frames per trajectory.
        n_objects: its objects per scene.
        seed: the analyses' and the bootstrap's seed.
        bootstrap: trajectory resamples of the 95 % intervals (0: none).
        workers: worker processes of each analysis.
        analyzer: the analyses' other settings (``AnalyzerConfig.to_dict()``).
        title: the figure's title.
        rows: the baselines' rows (``budget`` 0), then one row per (method, budget): each
            question of :data:`QUESTIONS` with its ``_low`` and ``_high`` interval bounds (AP in
            [0, 1], ``None`` with one class of labels), ``runtime_per_frame_s`` (s),
            ``nodes_per_frame`` and ``frames`` (the columns :data:`FIELDS`).

    """

    dataset: str
    task: str
    n_trajectories: int
    n_frames: int
    n_objects: int
    seed: int
    bootstrap: int
    workers: int
    analyzer: dict[str, Any]
    title: str
    rows: list[dict[str, Any]]

    def __getitem__(self, key: str | int | slice) -> Any:
        if isinstance(key, str):
            return super().__getitem__(key)
        warnings.warn(
            f"BudgetSweepResult[{key!r}] reads the result as the list of rows of earlier releases, which goes "
            f"in 0.3; use .rows[{key!r}]",
            DeprecationWarning,
            stacklevel=2,
        )
        return self.rows[key]


def budget_run(work: Path, out: Path) -> RunSpec:
    """The run of a sweep in the work directory ``work`` whose summary is ``out``.

    The dataset, the seed and the analyzer settings decide the analyses a sweep keeps; budgets,
    methods, the bootstrap and the workers may change between runs (every summary is computed
    afresh from the analyses). The work directory may hold other files (``--out`` may name a file
    in any folder, and a sweep of an earlier release has no settings file): ``overwrite`` removes
    only the summary, its JSON and PNG and the ``<method>-<budget>`` analyses.
    """
    entries = work.iterdir() if work.is_dir() else iter(())
    found = sorted(e.name for e in entries if e.is_dir() and _CONFIGURATION.match(e.name))
    return RunSpec(
        contents="a budget sweep",
        settings_file=SETTINGS_FILE,
        outputs=(out.name, out.with_suffix(".json").name, out.with_suffix(".png").name, *found),
        compared=("dataset", "seed", "analyzer"),
        shared_directory=True,
    )


def sweep_settings(
    dataset: Dataset,
    *,
    expansions: Sequence[int],
    methods: Sequence[str],
    seed: int,
    bootstrap: int,
    workers: int,
    base: AnalyzerConfig,
) -> dict[str, Any]:
    """What ``budget_settings.json`` records of a sweep (its ``budgets``: ``expansions``, as in 0.2)."""
    return {
        "dataset": dataset.identity(),
        "seed": seed,
        "analyzer": base.to_dict(),
        "budgets": list(expansions),
        "methods": list(methods),
        "bootstrap": bootstrap,
        "workers": workers,
    }


def _write_tables(rows: list[dict[str, Any]], out: Path, meta: dict[str, Any]) -> list[Path]:
    return [write_csv(out, rows, FIELDS), write_json(out.with_suffix(".json"), {**meta, "rows": rows})]


def plot(
    rows: list[dict[str, Any]],
    path: Path,
    *,
    title: str = "",
    questions: Sequence[str] = QUESTIONS,
    labels: dict[str, str] | None = None,
) -> Path | None:
    """Write the :class:`~energy_margin.experiments.budget_display.BudgetDisplay` of ``rows`` to ``path``.

    Args:
        rows: summary rows (``method``, ``budget`` and each question with ``_low``/``_high``);
            rows of a method outside the tree methods are drawn as horizontal baselines.
        path: the PNG to write.
        title: figure title.
        questions: the questions, one panel each.
        labels: panel titles by question (default :data:`QUESTION_LABELS`).

    Returns:
        ``path``, or ``None`` without matplotlib.

    """
    labels = labels if labels is not None else QUESTION_LABELS
    return BudgetDisplay.from_result(rows, questions=questions, labels=labels, title=title).save(path)


def _check_sweep(budgets: Sequence[int], methods: Sequence[str], workers: int, seed: int, bootstrap: int) -> None:
    if not budgets:
        raise InvalidParameterError("expansions", f"must be integers >= 1, got {list(budgets)!r}")
    for budget in budgets:
        check_int("expansions", budget, minimum=1)
    if not methods:
        raise InvalidParameterError("methods", f"must be among {', '.join(METHODS)}, got {list(methods)!r}")
    for method in methods:
        check_choice("methods", method, METHODS)
    check_int("workers", workers, minimum=1)
    check_int("bootstrap", bootstrap, minimum=0)
    check_seed(seed)


@renamed_keyword(budgets="expansions")
def budget_sweep(
    path: Path | str,
    *,
    expansions: Sequence[int] = DEFAULT_BUDGETS,
    methods: Sequence[str] = METHODS,
    workers: int = 1,
    seed: int = 0,
    bootstrap: int = 1000,
    out: Path | str | None = None,
    base: AnalyzerConfig | None = None,
    overwrite: bool = False,
    log: Callable[[str], None] | None = None,
) -> BudgetSweepResult:
    """Analyse the dataset at every (method, budget), write the summary and return it.

    The work directory (``DIR/budget/``, or the folder of ``out``) is opened as a run
    (:func:`energy_margin.runs.open_run`): ``budget_settings.json`` is written first and the
    directory stays locked while the sweep runs. Every configuration resumes on its own; the
    summary tables are rewritten as configurations finish and the figure drawn at the end.

    Args:
        path: dataset directory.
        expansions: the budgets to compare, expansions per frame, each >= 1.
        methods: tree methods.
        workers: worker processes of each analysis.
        seed: analysis seed (the same per-frame seeds for every configuration) and bootstrap seed.
        bootstrap: trajectory resamples for the confidence intervals (0: none).
        out: summary CSV (JSON and PNG beside it); ``DIR/budget/budget.csv`` by default.
        base: other analysis settings (cost, lambda, batch, ...); its expansions are replaced.
        overwrite: replace a sweep of another dataset, seed or analyzer settings in the work
            directory (its summary and analyses) instead of refusing.
        log: receives one progress line per configuration (standard error by default).

    Returns:
        The summary: the dataset, the settings and the rows (:class:`BudgetSweepResult`).

    """
    _check_sweep(expansions, methods, workers, seed, bootstrap)
    say = log if log is not None else (lambda line: print(line, file=sys.stderr, flush=True))
    directory = Path(path)
    dataset = load_dataset(directory)
    out_path = Path(out) if out is not None else directory / WORK_DIR / "budget.csv"
    base = base if base is not None else AnalyzerConfig()
    settings = sweep_settings(
        dataset, expansions=expansions, methods=methods, seed=seed, bootstrap=bootstrap, workers=workers, base=base
    )
    work = out_path.parent
    with run_directory(work, budget_run(work, out_path), settings, overwrite=overwrite, engine=base.engine):
        meta = {
            "dataset": str(directory),
            "task": dataset.metadata["task"],
            "n_trajectories": dataset.n_trajectories,
            "n_frames": dataset.n_frames,
            "n_objects": dataset.n_objects,
            "seed": seed,
            "bootstrap": bootstrap,
            "workers": workers,
            "analyzer": base.to_dict(),
            "title": f"{dataset.metadata['task']}, n_o = {dataset.n_objects}, "
            f"{dataset.n_trajectories} x {dataset.n_frames} frames",
        }
        rows = _sweep_rows(directory, dataset, out_path, meta, base, expansions, methods, say)
        _write_tables(rows, out_path, meta)
        plot(rows, out_path.with_suffix(".png"), title=meta["title"])
    return BudgetSweepResult(**meta, rows=rows)


def _sweep_rows(
    directory: Path,
    dataset: Dataset,
    out: Path,
    meta: dict[str, Any],
    base: AnalyzerConfig,
    budgets: Sequence[int],
    methods: Sequence[str],
    say: Callable[[str], None],
) -> list[dict[str, Any]]:
    """The baselines' rows and every configuration's, the tables rewritten after each configuration."""
    seed, bootstrap = meta["seed"], meta["bootstrap"]
    questions = Questions(dataset)
    resamples = np.random.default_rng(seed).integers(0, dataset.n_trajectories, (bootstrap, dataset.n_trajectories))
    rows: list[dict[str, Any]] = []
    for name, grids in baseline_grids(dataset).items():
        rows.append({"method": name, "budget": 0, **summarize(questions, *grids, resamples), "frames": 0})
    total = len(methods) * len(budgets)
    for number, (method, budget) in enumerate(((m, b) for m in methods for b in budgets), start=1):
        started = time.perf_counter()
        work = out.parent / f"{method}-{budget}"
        scores = analyze_configuration(
            directory, work, base, method=method, budget=budget, seed=seed, workers=meta["workers"]
        )
        capture = score_grid(dataset, scores, "capture_score")
        success = score_grid(dataset, scores, "success_score")
        row: dict[str, Any] = {"method": method, "budget": budget}
        row.update(summarize(questions, capture, success, resamples))
        row.update(cost_summary(scores))
        rows.append(row)
        _write_tables(rows, out, meta)
        say(
            f"budget [{number}/{total}] {method} {budget}: capture AP {fmt(row['capture_ap'])}, "
            f"k-hat=2 {fmt(row['capture_ap_window2'])}, success (first half) {fmt(row['success_ap_first_half'])}, "
            f"{row['runtime_per_frame_s']:.3f} s/frame ({time.perf_counter() - started:.0f} s)"
        )
    return rows


def analyze_configuration(
    directory: Path,
    work: Path,
    base: AnalyzerConfig,
    *,
    method: str,
    budget: int,
    seed: int,
    workers: int,
    progress: Progress = False,
) -> dict[str, np.ndarray]:
    """Analyse the dataset ``directory`` with ``method`` at ``budget`` iterations in its own ``work`` directory.

    ``work`` gets a copy of the dataset files and the resumable journal of
    :func:`energy_margin.analysis.run.analyze`; a finished configuration is read back, not rerun.

    Returns:
        The scores columns (:func:`energy_margin.data.scores_file.load_scores`).

    """
    copy_dataset(directory, work)
    fields = {**base.to_dict(), "expansions": budget, "nodes": None, "method": method}
    try:
        config = AnalyzerConfig(**fields).fixed_continuation()
    except ValueError as error:
        raise EnergyMarginError(str(error)) from None
    analyze(work, config, seed=seed, workers=workers, progress=progress)
    return load_scores(work)


def cost_summary(scores: dict[str, np.ndarray]) -> dict[str, Any]:
    """Mean wall time and nodes per frame of a scores file's columns, and its number of frames."""
    return {
        "runtime_per_frame_s": float(scores["runtime_s"].mean()),
        "nodes_per_frame": float(scores["nodes"].mean()),
        "frames": int(scores["runtime_s"].size),
    }


def _interval(question: str) -> Callable[[dict[str, Any]], str]:
    def cell(row: dict[str, Any]) -> str:
        value, low, high = row.get(question), row.get(f"{question}_low"), row.get(f"{question}_high")
        return fmt(value) if low is None or high is None else f"{fmt(value)} [{low:.3f}, {high:.3f}]"

    return cell


def _name(key: str) -> Callable[[dict[str, Any]], str]:
    return lambda row: str(row.get(key, ""))


def _runtime(row: dict[str, Any]) -> str:
    runtime = row.get("runtime_per_frame_s")
    return "" if runtime is None else f"{runtime:.3f}"


def table_columns(
    rows: Sequence[dict[str, Any]], *, questions: Sequence[str], headers: Sequence[str], first: Sequence[str]
) -> list[Column]:
    """The columns of :func:`format_table`: the ``first`` keys (one width), the budget, the questions, s/frame."""
    width = max([13, *(len(str(row.get(key, ""))) for row in rows for key in first)])
    return [
        *(Column(key, _name(key), width) for key in first),
        Column("budget", lambda row: str(row["budget"]) if row.get("budget") else "-", 6),
        *(Column(header, _interval(q), 24) for q, header in zip(questions, headers, strict=True)),
        Column("s/frame", _runtime, 8),
    ]


def format_table(
    rows: list[dict[str, Any]],
    *,
    questions: Sequence[str] = QUESTIONS,
    headers: Sequence[str] = ("capture k=0", "capture k=2", "success 1st half"),
    first: Sequence[str] = ("method",),
) -> str:
    """A text table of summary rows: the ``first`` columns, the budget, each question with its interval."""
    return tables.format_table(rows, table_columns(rows, questions=questions, headers=headers, first=first))
