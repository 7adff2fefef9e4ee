"""Design sweeps: does the energy margin rank task designs as their real outcomes do?

A design is one setting of a task's configuration (e.g. the scooping blade angle and finger gap).
``design_sweep`` walks the Cartesian product of the swept values (:func:`design_grid`, from the
``NAME=A,B,C`` values of :func:`~energy_margin.design.params.parse_param`); for every design it generates T
randomised trajectories (:func:`~energy_margin.data.generate.generate_dataset`), analyses their frames
(:func:`~energy_margin.analysis.run.analyze`) and reports

* the actual success rate over the T trajectories (from the labels) with its 95 % Wilson interval;
* the mean capture and success scores of all its frames, and the mean early success prediction
  (``trajectory_success_score`` of the first half of each trajectory's frames, the last three of
  them linearly weighted: the question ``evaluate`` calls "success from the first half").

Across designs it reports Spearman's rank correlation of each margin column with the success
rate (permutation p-value, and a 95 % interval from paired trajectory resamples), and how that
correlation grows with the number of trajectories t the margin is computed from, beside the rank
correlation of the success rate measured on t trajectories: the answer to "does the margin rank
designs as their outcomes do, from fewer trajectories?" (:mod:`~energy_margin.design.rank`).
The results are written, and printed, by :mod:`~energy_margin.design.sweep_results`, the
figure drawn by :class:`~energy_margin.design.sweep_display.SweepDisplay`.

Seeds: every design is generated with the same seed and analysed with the same seed, so trajectory
i of every design starts from the same random draws (box positions, yaw, friction, drive; the draws
do not depend on the swept settings), and frame j of trajectory i gets the same analysis seed:
common random numbers make the comparison of designs paired.

Layout of the output directory, a run directory (:func:`~energy_margin.runs.open_run`, locked for
the whole sweep)::

    DIR/sweep.json                 the resolved settings, written first (checked again when a sweep resumes)
    DIR/designs/<design>/          one dataset per design, with its scores.csv
    DIR/results.csv, results.json  the table; the JSON adds correlations and per-trajectory values
    DIR/results.png                the figure (with matplotlib, the ``plot`` extra)

A design whose dataset and scores are complete is skipped on a rerun; a partly analysed one
resumes from its journal. A sweep of other settings is refused unless ``overwrite``, which removes
these files and nothing else. A design whose roll-outs cannot be generated, or are refused by the
analysis's checks (e.g. boxes pressed into the blades deeper than the overlap limit), is listed
as not analysed, with the reason, and left out of the correlations.
"""

from __future__ import annotations

import dataclasses
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.run import analyze
from energy_margin.data.dataset import Dataset, load_dataset
from energy_margin.data.generate import check_engine, generate_dataset
from energy_margin.data.scores_file import SCORES_FILE, load_scores
from energy_margin.design.grid import Design, design_grid
from energy_margin.design.rank import (
    EARLY_SUCCESS_FRAMES,
    MARGIN_LABELS,
    MARGINS,
    DesignOutcome,
    default_trajectory_counts,
    design_outcome,
    rank_convergence,
    rank_correlations,
)
from energy_margin.design.sweep_display import SweepDisplay
from energy_margin.design.sweep_results import (
    FIGURE_FILE,
    RESULTS_FILE,
    RESULTS_JSON,
    SweepResult,
    design_row,
    failed_row,
    format_table,
    summarize,
    table_fields,
    write_results,
)
from energy_margin.errors import EnergyMarginError, check_choice, check_int, check_seed
from energy_margin.runs import RunSpec, progress_bar, run_directory
from energy_margin.runs.progress import Progress
from energy_margin.sim import ENGINES
from energy_margin.tasks import Task, resolve_task

__all__ = [
    "DESIGNS_DIR",
    "EARLY_SUCCESS_FRAMES",
    "MARGINS",
    "MARGIN_LABELS",
    "RESULTS_FILE",
    "SETTINGS_FILE",
    "SWEEP_RUN",
    "Design",
    "DesignOutcome",
    "SweepDisplay",
    "SweepResult",
    "default_trajectory_counts",
    "design_grid",
    "design_outcome",
    "design_row",
    "design_sweep",
    "failed_row",
    "format_table",
    "rank_convergence",
    "rank_correlations",
    "summarize",
    "table_fields",
    "write_results",
]

SETTINGS_FILE = "sweep.json"
DESIGNS_DIR = "designs"
#: The settings that decide a sweep's results: a rerun with others is another sweep. The grid
#: (``params``, ``designs``) may grow: a design's directory is named by its values.
RESUME_KEYS = ("task", "n_objects", "n_trajectories", "n_frames", "seed", "engine", "fixed", "analyzer")
#: A design sweep's run directory: ``sweep.json``, then the designs' datasets and the results.
SWEEP_RUN = RunSpec(
    contents="a sweep",
    settings_file=SETTINGS_FILE,
    outputs=(DESIGNS_DIR, RESULTS_FILE, RESULTS_JSON, FIGURE_FILE),
    compared=RESUME_KEYS,
)


def _settings(
    task: Task,
    params: Sequence[tuple[str, Sequence[Any]]],
    designs: Sequence[Design],
    *,
    n_objects: int | None,
    n_trajectories: int,
    n_frames: int,
    seed: int,
    engine: str,
    fixed: dict[str, Any],
    analyzer: AnalyzerConfig,
) -> dict[str, Any]:
    """The contents of ``sweep.json``: the settings of :data:`RESUME_KEYS`, then the grid."""
    settings: dict[str, Any] = {
        "task": task.name,
        "n_objects": n_objects,
        "n_trajectories": n_trajectories,
        "n_frames": n_frames,
        "seed": seed,
        "engine": engine,
        "fixed": fixed,
        "analyzer": analyzer.to_dict(),
    }
    settings["params"] = [{"name": name, "values": list(values)} for name, values in params]
    settings["aliases"] = {alias.name: alias.doc for alias in task.design_aliases()}
    settings["designs"] = [{"design": d.slug, "values": d.values, "task_config": d.overrides} for d in designs]
    return settings


def _check_numbers(
    *,
    n_trajectories: int,
    n_frames: int,
    seed: int,
    workers: int,
    bootstrap: int,
    subsets: int,
    counts: Sequence[int] | None,
) -> list[int]:
    """Check the counts of a sweep; the t of the convergence table, each an integer in [1, T]."""
    check_int("n_trajectories", n_trajectories, minimum=2)
    check_int("n_frames", n_frames, minimum=1)
    check_seed(seed)
    check_int("workers", workers, minimum=1)
    check_int("bootstrap", bootstrap, minimum=1)
    check_int("subsets", subsets, minimum=1)
    if counts is None:
        return default_trajectory_counts(n_trajectories)
    return [check_int("trajectory_counts", count, minimum=1, maximum=n_trajectories) for count in counts]


def task_settings(
    task: Task, n_objects: int | None, engine: str, analyzer: AnalyzerConfig | None
) -> tuple[int, AnalyzerConfig]:
    """The objects per scene and the analysis settings of a sweep of ``task`` on ``engine``, checked."""
    n_objects = _objects(task, n_objects)
    check_choice("engine", engine, ENGINES)
    check_engine(task, engine, records=True)
    # AnalyzerConfig raises InvalidParameterError naming the field.
    chosen = analyzer if analyzer is not None else AnalyzerConfig()
    return n_objects, dataclasses.replace(chosen, engine=engine).fixed_continuation()


def _objects(task: Task, n_objects: int | None) -> int:
    """The objects per scene of a sweep of ``task``, checked before anything is written."""
    if task.fixed_objects is not None:
        if n_objects is not None and n_objects != task.fixed_objects:
            raise EnergyMarginError(f"{task.label} has {task.fixed_objects} objects; `n_objects={n_objects}` differs")
        return task.fixed_objects
    if n_objects is None:
        raise EnergyMarginError(f"{task.label} needs the number of objects (`n_objects`)")
    return check_int("n_objects", n_objects, minimum=1)


def _generate(task: Task, design: Design, directory: Path, settings: dict[str, Any], *, progress: Progress) -> Dataset:
    pending = not (directory / SCORES_FILE).is_file()
    bar = progress_bar(settings["n_trajectories"], desc="generate", unit="traj", enabled=progress if pending else False)
    try:
        return generate_dataset(
            task,
            n_objects=settings["n_objects"],
            n_trajectories=settings["n_trajectories"],
            n_frames=settings["n_frames"],
            seed=settings["seed"],
            out=directory,
            engine=settings["engine"],
            task_config=design.overrides,
            progress=bar.update,
        )
    finally:
        bar.close()


@dataclass
class _Sweep:
    """A sweep under way: what it runs, and the designs analysed (or not) so far."""

    task: Task
    designs: list[Design]
    settings: dict[str, Any]
    analyzer: AnalyzerConfig
    counts: list[int]
    seed: int
    workers: int
    bootstrap: int
    subsets: int
    progress: Progress
    say: Callable[[str], None]
    rows: list[dict[str, Any]] = dataclasses.field(default_factory=list)
    outcomes: list[DesignOutcome] = dataclasses.field(default_factory=list)
    failed: list[dict[str, Any]] = dataclasses.field(default_factory=list)

    def run(self, out: Path) -> dict[str, Any]:
        """Every design in turn, the results rewritten after each; the final results."""
        results: dict[str, Any] = {}
        for number, design in enumerate(self.designs, start=1):
            self.design(f"sweep [{number}/{len(self.designs)}] {design.label}", design, out / DESIGNS_DIR / design.slug)
            results = self.results()
            write_results(out, results)
        return results

    def design(self, prefix: str, design: Design, directory: Path) -> None:
        """Generate and analyse one design (resuming its files), and report it in one line."""
        started = time.perf_counter()
        finished = (directory / SCORES_FILE).is_file()
        try:
            _generate(self.task, design, directory, self.settings, progress=self.progress)
            analyze(directory, self.analyzer, seed=self.seed, workers=self.workers, progress=self.progress)
        except EnergyMarginError as error:
            # A design whose roll-outs cannot be generated or analysed (e.g. a blade angle that
            # drives the boxes into the gripper) is reported as such; the sweep goes on.
            self.failed.append(failed_row(design, directory, str(error)))
            self.say(f"{prefix}: not analysed: {error}")
            return
        outcome = design_outcome(load_dataset(directory), load_scores(directory))
        row = design_row(design, outcome)
        self.rows.append(row)
        self.outcomes.append(outcome)
        self.say(
            f"{prefix}: success {row['successes']}/{row['trajectories']} "
            f"[{row['success_rate_low']:.2f}, {row['success_rate_high']:.2f}], early success score "
            f"{row['early_success_score']:.4f}, capture score {row['capture_score']:.4f} "
            + ("(already analysed)" if finished else f"({time.perf_counter() - started:.0f} s)")
        )

    def results(self) -> dict[str, Any]:
        """The results of the designs so far (:func:`summarize`, with the designs not analysed)."""
        results = summarize(
            self.settings,
            self.rows,
            self.outcomes,
            self.counts,
            seed=self.seed,
            bootstrap=self.bootstrap,
            subsets=self.subsets,
        )
        results["failed"] = self.failed
        return results


def design_sweep(
    task: str | Task,
    params: Sequence[tuple[str, Sequence[Any]]],
    *,
    n_trajectories: int,
    n_frames: int = 10,
    n_objects: int | None = None,
    seed: int = 0,
    out: Path | str,
    workers: int = 1,
    engine: str = "mujoco",
    fixed: dict[str, Any] | None = None,
    analyzer: AnalyzerConfig | None = None,
    trajectory_counts: Sequence[int] | None = None,
    bootstrap: int = 2000,
    subsets: int = 200,
    overwrite: bool = False,
    progress: Progress = False,
    log: Callable[[str], None] | None = None,
) -> SweepResult:
    """Generate, analyse and compare every design of the grid; write and return the results.

    Every argument is checked, and every design built, before anything is written; the sweep
    then holds the lock of ``out`` until it returns, so a second sweep writing there is refused.

    Args:
        task: a registered task's name, or a task object (:func:`~energy_margin.tasks.resolve_task`).
        params: ``(name, values)`` per swept parameter (see :func:`design_grid`).
        n_trajectories: trajectories T per design, >= 2.
        n_frames: frames per trajectory, >= 1.
        n_objects: objects per scene (``None`` for a task that fixes them).
        seed: generation and analysis seed of every design (common random numbers), also of the
            resamples.
        out: the sweep directory (created; a rerun with the same settings resumes it).
        workers: analysis worker processes, >= 1.
        engine: physics engine of generation and analysis.
        fixed: configuration overrides of every design.
        analyzer: analysis settings (its engine is replaced by ``engine``).
        trajectory_counts: the t of :func:`rank_convergence`, each in [1, T]
            (default :func:`default_trajectory_counts`).
        bootstrap: trajectory resamples of the correlations' intervals, >= 1.
        subsets: random trajectory subsets per t in :func:`rank_convergence`, >= 1.
        overwrite: replace a sweep of other settings in ``out`` (its own files only: ``sweep.json``,
            ``designs/`` and the results) instead of refusing.
        progress: show generation and analysis progress bars on standard error.
        log: receives one line per design (standard error by default).

    Returns:
        The :class:`~energy_margin.design.sweep_results.SweepResult`, whose ``to_dict()`` is
        ``results.json``: ``settings``, ``rows`` (one per analysed design),
        ``correlations`` and ``convergence`` (with at least two), ``trajectories`` (per-trajectory
        values of each design) and ``failed`` (designs that could not be generated or analysed,
        each with its error and, when its roll-outs exist, the labels' success rate).

    Raises:
        EnergyMarginError: a bad argument or design (:class:`~energy_margin.errors.InvalidParameterError`
            for a bad number), ``out`` holding something else or a sweep of other settings, or
            ``out`` being written by another live process.

    """
    numbers = {"n_trajectories": n_trajectories, "n_frames": n_frames, "seed": seed}
    counts = _check_numbers(**numbers, workers=workers, bootstrap=bootstrap, subsets=subsets, counts=trajectory_counts)
    fixed = dict(fixed or {})
    resolved = resolve_task(task, fixed)
    designs = design_grid(resolved, params, fixed=fixed)
    n_objects, analyzer = task_settings(resolved, n_objects, engine, analyzer)
    settings = _settings(
        resolved, params, designs, n_objects=n_objects, **numbers, engine=engine, fixed=fixed, analyzer=analyzer
    )
    say = log if log is not None else (lambda line: print(line, file=sys.stderr, flush=True))
    sweep = _Sweep(resolved, designs, settings, analyzer, counts, seed, workers, bootstrap, subsets, progress, say)
    with run_directory(out, SWEEP_RUN, settings, overwrite=overwrite, engine=engine) as run:
        return SweepResult.from_dict(sweep.run(run.path))
