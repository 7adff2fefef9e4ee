"""Design sweeps: does the energy margin rank task designs as their real outcomes do?

A design is one setting of a task's configuration (e.g. the scooping blade angle and finger gap).
``design_sweep`` walks the Cartesian product of the swept values; for every design it generates T
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
designs as their outcomes do, from fewer trajectories?".

Seeds: every design is generated with the same seed and analysed with the same seed, so trajectory
i of every design starts from the same random draws (box positions, yaw, friction, drive; the draws
do not depend on the swept settings), and frame j of trajectory i gets the same analysis seed:
common random numbers make the comparison of designs paired.

Layout of the output directory::

    DIR/sweep.json                 the resolved settings (checked again when a sweep resumes)
    DIR/designs/<design>/          one dataset per design, with its scores.csv
    DIR/results.csv, results.json  the table; the JSON adds correlations and per-trajectory values
    DIR/results.png                the plot (with matplotlib, the ``plot`` extra)

A design whose dataset and scores are complete is skipped on a rerun; a partly analysed one
resumes from its journal. A design whose roll-outs cannot be generated, or are refused by the
analysis's checks (e.g. boxes pressed into the blades deeper than the overlap limit), is listed
as not analysed, with the reason, and left out of the correlations.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import itertools
import json
import re
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.run import analyze
from energy_margin.analysis.scores import trajectory_success_score
from energy_margin.data.dataset import Dataset, load_dataset
from energy_margin.data.generate import check_engine, generate_dataset
from energy_margin.data.scores_file import SCORES_FILE, load_scores
from energy_margin.errors import EnergyMarginError
from energy_margin.evaluation.metrics import score_grid
from energy_margin.evaluation.statistics import spearman, spearman_rho, wilson_interval
from energy_margin.runs.files import atomic_write_text, leftovers, read_json, remove_leftovers, write_json
from energy_margin.sim import ENGINES
from energy_margin.tasks import Task, available_tasks, get_task

SETTINGS_FILE = "sweep.json"
RESULTS_FILE = "results.csv"
DESIGNS_DIR = "designs"
#: k-bar of the early success prediction (as ``evaluate`` and ``budget``).
EARLY_SUCCESS_FRAMES = 3
#: The margin columns ranked against the success rate, first the one that matters most.
MARGINS = ("early_success_score", "success_score", "capture_score")
MARGIN_LABELS = {
    "early_success_score": "early success score (first half)",
    "success_score": "success score (all frames)",
    "capture_score": "capture score (all frames)",
}


@dataclass(frozen=True)
class DesignAlias:
    """A design parameter that is not a configuration field itself but sets one.

    Attributes:
        name: the parameter's name on the command line.
        field: the configuration field it sets.
        doc: what the parameter is, with its unit.
        to_field: the field's value for a parameter value, given the field's current value.

    """

    name: str
    field: str
    doc: str
    to_field: Callable[[Any, Any], Any]


def _single_stiffness(value: Any, current: Any) -> Any:
    del current
    return [value, value]


def _pusher_width(value: Any, current: Any) -> Any:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ValueError(f"pusher_width must be a number, got {value!r}")
    return [value / 2.0, current[1], current[2]]


#: Friendly design parameters per task (every configuration field can be swept by its own name too).
DESIGN_ALIASES: dict[str, tuple[DesignAlias, ...]] = {
    "scooping": (
        DesignAlias(
            "finger_stiffness",
            "stiffness_range",
            "finger drive stiffness, N/m: every trajectory uses this one value (stiffness_range = [v, v]) "
            "instead of a log-uniform draw",
            _single_stiffness,
        ),
    ),
    "pushing": (
        DesignAlias(
            "pusher_width",
            "pusher_half_extents",
            "full pusher width along x, m (pusher_half_extents[0] = v / 2; depth and height unchanged)",
            _pusher_width,
        ),
    ),
}


@dataclass(frozen=True)
class Design:
    """One point of the grid.

    Attributes:
        values: the swept parameters' values, in the order of the parameters.
        overrides: the task configuration overrides of this design (fixed settings included).
        slug: the design's directory name under ``DIR/designs``.

    """

    values: dict[str, Any]
    overrides: dict[str, Any]
    slug: str

    @property
    def label(self) -> str:
        """The design as people read it, e.g. ``scoop_angle=1.31, open_gap=0.09``."""
        return _label(self.values)


def parse_param(text: str) -> tuple[str, list[Any]]:
    """``NAME=V1,V2,...`` as the name and its list of values (each value JSON: a number or a list).

    Raises:
        EnergyMarginError: no ``=``, an empty name, values that are not comma-separated JSON, an
            empty list or a value given twice.

    """
    name, sep, values_text = text.partition("=")
    name = name.strip()
    if not sep or not name:
        raise EnergyMarginError(f"--param expects NAME=V1,V2,..., got {text!r}")
    try:
        values = json.loads(f"[{values_text}]")
    except json.JSONDecodeError:
        raise EnergyMarginError(
            f"--param {name}: {values_text!r} is not a comma-separated list of values (numbers, or JSON lists)"
        ) from None
    if not values:
        raise EnergyMarginError(f"--param {name}: no values given")
    seen: list[Any] = []
    for value in values:
        if value in seen:
            raise EnergyMarginError(f"--param {name}: value {json.dumps(value)} is listed twice")
        seen.append(value)
    return name, values


def _config_fields(task: Task) -> dict[str, Any]:
    return {field.name: getattr(task.config, field.name) for field in dataclasses.fields(task.config)}


def _design_names(task_name: str) -> set[str] | None:
    """Every parameter name a sweep of ``task_name`` accepts; ``None`` when its default cannot be built."""
    try:
        task = get_task(task_name)
    except EnergyMarginError:
        return None
    return set(_config_fields(task)) | {alias.name for alias in DESIGN_ALIASES.get(task_name, ())}


def _unknown_parameter(task_name: str, name: str, known: set[str]) -> EnergyMarginError:
    owners = [other for other in available_tasks() if other != task_name and name in (_design_names(other) or set())]
    if owners:
        return EnergyMarginError(
            f"--param {name} is a setting of task {owners[0]!r}, not of {task_name!r} (sweep --task {owners[0]})"
        )
    aliases = [alias.name for alias in DESIGN_ALIASES.get(task_name, ())]
    hint = f"{', '.join(aliases)} or a {task_name} setting" if aliases else f"a {task_name} setting"
    return EnergyMarginError(
        f"unknown {task_name} parameter {name!r}; sweepable: {hint} ({', '.join(sorted(known - set(aliases)))})"
    )


def design_grid(
    task_name: str, params: Sequence[tuple[str, Sequence[Any]]], *, fixed: dict[str, Any] | None = None
) -> list[Design]:
    """Every design of the Cartesian product of ``params``, validated against the task's configuration.

    Args:
        task_name: a registered task.
        params: ``(name, values)`` per swept parameter: a configuration field or an alias of
            :data:`DESIGN_ALIASES`.
        fixed: configuration overrides shared by every design (``--set``).

    Raises:
        EnergyMarginError: an unknown task or parameter, a parameter of another task, a parameter
            given twice or also fixed, or a design whose configuration is invalid (named).

    """
    fixed = dict(fixed or {})
    base = get_task(task_name, fixed)
    fields = _config_fields(base)
    aliases = {alias.name: alias for alias in DESIGN_ALIASES.get(task_name, ())}
    known = set(fields) | set(aliases)
    if not params:
        raise EnergyMarginError("a sweep needs at least one --param NAME=V1,V2,...")
    targets: dict[str, str] = {}
    for name, values in params:
        if name not in known:
            raise _unknown_parameter(task_name, name, known)
        field = aliases[name].field if name in aliases else name
        if field in targets:
            raise EnergyMarginError(f"--param {name} sets {field}, as --param {targets[field]} does")
        if field in fixed:
            raise EnergyMarginError(f"--param {name} sets {field}, which --set fixes for every design")
        if not values:
            raise EnergyMarginError(f"--param {name}: no values given")
        targets[field] = name
    designs: list[Design] = []
    slugs: dict[str, str] = {}
    for combination in itertools.product(*(values for _, values in params)):
        chosen = {name: value for (name, _), value in zip(params, combination, strict=True)}
        label = _label(chosen)
        overrides = dict(fixed)
        for name, value in chosen.items():
            if name in aliases:
                alias = aliases[name]
                try:
                    overrides[alias.field] = alias.to_field(value, fields[alias.field])
                except ValueError as error:
                    raise EnergyMarginError(f"design {label}: {error}") from None
            else:
                overrides[name] = value
        try:
            get_task(task_name, overrides)
        except EnergyMarginError as error:
            raise EnergyMarginError(f"design {label}: {error}") from None
        slug = "__".join(f"{name}-{_token(value)}" for name, value in chosen.items())
        if slug in slugs:
            raise EnergyMarginError(f"designs {slugs[slug]} and {label} share the directory name {slug}")
        slugs[slug] = label
        designs.append(Design(values=chosen, overrides=overrides, slug=slug))
    return designs


def _label(values: dict[str, Any]) -> str:
    return ", ".join(f"{name}={json.dumps(value)}" for name, value in values.items())


def _token(value: Any) -> str:
    return re.sub(r"[^A-Za-z0-9.+-]+", "_", json.dumps(value)).strip("_") or "_"


def _check_int(name: str, value: Any, minimum: int) -> None:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < minimum:
        raise EnergyMarginError(f"{name} must be an integer >= {minimum}, got {value!r}")


@dataclass(frozen=True)
class DesignOutcome:
    """Per-trajectory values of one analysed design (T = trajectories).

    Attributes:
        success: success label of every trajectory, shape (T,).
        capture_score: mean capture score of each trajectory's frames, shape (T,).
        success_score: mean success score of each trajectory's frames, shape (T,).
        early_success_score: early success prediction of each trajectory, shape (T,).
        runtime_per_frame_s: mean analysis time of a frame, s.

    """

    success: np.ndarray
    capture_score: np.ndarray
    success_score: np.ndarray
    early_success_score: np.ndarray
    runtime_per_frame_s: float

    def column(self, name: str) -> np.ndarray:
        """The per-trajectory array of ``name`` (``"success"`` or a :data:`MARGINS` entry)."""
        return np.asarray(getattr(self, name), dtype=float)


def design_outcome(dataset: Dataset, scores: dict[str, np.ndarray]) -> DesignOutcome:
    """The per-trajectory values of a dataset and its ``scores.csv`` columns."""
    capture = score_grid(dataset, scores, "capture_score")
    success = score_grid(dataset, scores, "success_score")
    half = max(1, dataset.n_frames // 2)
    return DesignOutcome(
        success=dataset.success_labels().astype(bool),
        capture_score=capture.mean(axis=1),
        success_score=success.mean(axis=1),
        early_success_score=trajectory_success_score(success[:, :half], last=EARLY_SUCCESS_FRAMES),
        runtime_per_frame_s=float(np.mean(scores["runtime_s"])),
    )


def design_row(design: Design, outcome: DesignOutcome) -> dict[str, Any]:
    """The table row of one design: its values, success rate with Wilson interval and mean scores."""
    trials = int(outcome.success.size)
    successes = int(outcome.success.sum())
    low, high = wilson_interval(successes, trials)
    row: dict[str, Any] = {"design": design.slug, **design.values}
    row.update(
        trajectories=trials,
        successes=successes,
        success_rate=successes / trials,
        success_rate_low=low,
        success_rate_high=high,
    )
    for name in MARGINS:
        row[name] = float(outcome.column(name).mean())
    row["runtime_per_frame_s"] = outcome.runtime_per_frame_s
    return row


def _rates(outcomes: Sequence[DesignOutcome], rows: np.ndarray) -> np.ndarray:
    return np.array([o.column("success")[rows].mean() for o in outcomes])


def _means(outcomes: Sequence[DesignOutcome], name: str, rows: np.ndarray) -> np.ndarray:
    return np.array([o.column(name)[rows].mean() for o in outcomes])


def rank_correlations(
    outcomes: Sequence[DesignOutcome], *, seed: int = 0, bootstrap: int = 2000
) -> dict[str, dict[str, Any]]:
    """Spearman's rho of each margin column against the success rate across designs.

    Every entry has ``rho``, its permutation ``p_value`` (``exact`` when every ordering was
    enumerated), ``n`` designs and a 95 % percentile interval ``low``/``high`` over ``bootstrap``
    resamples of the trajectory indices, the same indices for every design (the designs share
    their trajectories' random draws); resamples where rho is undefined (a constant column) are
    left out and ``bootstrap_defined`` counts the others.
    """
    n_trajectories = outcomes[0].success.size
    everything = np.arange(n_trajectories)
    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(2)[0])
    resamples = rng.integers(0, n_trajectories, (bootstrap, n_trajectories))
    rates = _rates(outcomes, everything)
    result: dict[str, dict[str, Any]] = {}
    for name in MARGINS:
        correlation = spearman(_means(outcomes, name, everything), rates, seed=seed)
        samples = [spearman_rho(_means(outcomes, name, rows), _rates(outcomes, rows)) for rows in resamples]
        defined = [value for value in samples if value is not None]
        low, high = (float(v) for v in np.percentile(defined, [2.5, 97.5])) if defined else (None, None)
        result[name] = {
            "rho": correlation.rho,
            "p_value": correlation.p_value,
            "exact": correlation.exact,
            "n": correlation.n,
            "low": low,
            "high": high,
            "bootstrap_defined": len(defined),
        }
    return result


def default_trajectory_counts(n_trajectories: int) -> list[int]:
    """The t of the convergence table: 1, 2, 3, 5, 10, 15, 20, 30, 50, ... up to T, and T."""
    counts = [t for t in (1, 2, 3, 5, 10, 15, 20, 30, 50, 100, 200, 500) if t < n_trajectories]
    return [*counts, n_trajectories]


def rank_convergence(
    outcomes: Sequence[DesignOutcome], counts: Sequence[int], *, subsets: int = 200, seed: int = 0
) -> list[dict[str, Any]]:
    """Rank agreement with the success rate of all T trajectories when only t of them are used.

    For each t, ``subsets`` random sets of t trajectory indices (the same set for every design)
    give each design's margin means and success rate on those trajectories; each row reports, per
    margin column and for the success rate itself (``success_rate``), the mean over the subsets of
    Spearman's rho against the success rate of all T trajectories, and how many subsets had a
    defined rho (``<name>_defined``); a subset whose estimate is the same for every design (e.g. t
    = 1 with every design failing it) ranks nothing and counts as rho = 0 in the mean (``None``
    when no subset has a defined rho: the reference rates are all equal). At t = T there is one
    subset, all trajectories.
    """
    n_trajectories = outcomes[0].success.size
    reference = _rates(outcomes, np.arange(n_trajectories))
    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(2)[1])
    rows: list[dict[str, Any]] = []
    for t in counts:
        if t == n_trajectories:
            chosen = [np.arange(n_trajectories)]
        else:
            chosen = [np.sort(rng.choice(n_trajectories, size=t, replace=False)) for _ in range(subsets)]
        row: dict[str, Any] = {"trajectories": int(t), "subsets": len(chosen)}
        for name in (*MARGINS, "success_rate"):
            values = []
            for indices in chosen:
                estimate = _rates(outcomes, indices) if name == "success_rate" else _means(outcomes, name, indices)
                values.append(spearman_rho(estimate, reference))
            defined = [value for value in values if value is not None]
            # An estimate that ties every design ranks nothing: it counts as rho = 0.
            row[name] = float(np.mean([0.0 if value is None else value for value in values])) if defined else None
            row[f"{name}_defined"] = len(defined)
        rows.append(row)
    return rows


def _settings(
    task: str,
    *,
    n_objects: int | None,
    n_trajectories: int,
    n_frames: int,
    seed: int,
    engine: str,
    fixed: dict[str, Any],
    analyzer: AnalyzerConfig,
) -> dict[str, Any]:
    return {
        "task": task,
        "n_objects": n_objects,
        "n_trajectories": n_trajectories,
        "n_frames": n_frames,
        "seed": seed,
        "engine": engine,
        "fixed": fixed,
        "analyzer": analyzer.to_dict(),
    }


_RESUME_KEYS = ("task", "n_objects", "n_trajectories", "n_frames", "seed", "engine", "fixed", "analyzer")


def _check_directory(out: Path, settings: dict[str, Any]) -> None:
    """Refuse a directory that holds something else, or a sweep with other settings."""
    path = out / SETTINGS_FILE
    # What a sweep killed inside an atomic write left (a temporary file) is removed, not taken
    # for another directory's contents.
    names = (SETTINGS_FILE, RESULTS_FILE, "results.json", "results.png")
    remove_leftovers([p for name in names for p in leftovers(out, name)])
    if path.is_file():
        previous = read_json(path, what="sweep settings")
        if not isinstance(previous, dict):
            raise EnergyMarginError(f"{path}: not a sweep settings object")
        for key in _RESUME_KEYS:
            if json.dumps(previous.get(key), sort_keys=True) != json.dumps(settings[key], sort_keys=True):
                raise EnergyMarginError(
                    f"{out} holds a sweep with other settings ({key}: {json.dumps(previous.get(key))} there, "
                    f"{json.dumps(settings[key])} now); choose another --out"
                )
    elif out.is_file() or (out.exists() and any(out.iterdir())):
        raise EnergyMarginError(f"{out} exists and is not a sweep directory (no {SETTINGS_FILE})")


def design_sweep(
    task: str,
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
    progress: bool = False,
    log: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """Generate, analyse and compare every design of the grid; write and return the results.

    Args:
        task: a registered task.
        params: ``(name, values)`` per swept parameter (see :func:`design_grid`).
        n_trajectories: trajectories T per design, >= 2.
        n_frames: frames per trajectory, >= 1.
        n_objects: objects per scene (``None`` for a task that fixes them).
        seed: generation and analysis seed of every design (common random numbers), also of the
            resamples.
        out: the sweep directory (created; a rerun resumes it).
        workers: analysis worker processes, >= 1.
        engine: physics engine of generation and analysis.
        fixed: configuration overrides of every design.
        analyzer: analysis settings (its engine is replaced by ``engine``).
        trajectory_counts: the t of :func:`rank_convergence`, each in [1, T]
            (default :func:`default_trajectory_counts`).
        bootstrap: trajectory resamples of the correlations' intervals, >= 1.
        subsets: random trajectory subsets per t in :func:`rank_convergence`, >= 1.
        progress: show generation and analysis progress bars on standard error.
        log: receives one line per design (standard error by default).

    Returns:
        The contents of ``results.json``: ``settings``, ``rows`` (one per analysed design),
        ``correlations`` and ``convergence`` (with at least two), ``trajectories`` (per-trajectory
        values of each design) and ``failed`` (designs that could not be generated or analysed,
        each with its error and, when its roll-outs exist, the labels' success rate).

    """
    _check_int("trajectories", n_trajectories, 2)
    _check_int("frames", n_frames, 1)
    _check_int("seed", seed, 0)
    _check_int("workers", workers, 1)
    _check_int("bootstrap", bootstrap, 1)
    _check_int("subsets", subsets, 1)
    counts = list(trajectory_counts) if trajectory_counts is not None else default_trajectory_counts(n_trajectories)
    for count in counts:
        if isinstance(count, bool) or not isinstance(count, int) or not 1 <= count <= n_trajectories:
            raise EnergyMarginError(f"trajectory counts must be integers in [1, {n_trajectories}], got {count!r}")
    fixed = dict(fixed or {})
    designs = design_grid(task, params, fixed=fixed)
    n_objects = _objects(get_task(task, fixed), n_objects)
    if engine not in ENGINES:
        raise EnergyMarginError(f"unknown engine {engine!r}; choose one of {', '.join(ENGINES)}")
    check_engine(get_task(task, fixed), engine)
    try:
        analyzer = dataclasses.replace(analyzer if analyzer is not None else AnalyzerConfig(), engine=engine)
    except ValueError as error:
        raise EnergyMarginError(str(error)) from None
    say = log if log is not None else (lambda line: print(line, file=sys.stderr, flush=True))
    out = Path(out)
    settings = _settings(
        task,
        n_objects=n_objects,
        n_trajectories=n_trajectories,
        n_frames=n_frames,
        seed=seed,
        engine=engine,
        fixed=fixed,
        analyzer=analyzer,
    )
    _check_directory(out, settings)
    settings["params"] = [{"name": name, "values": list(values)} for name, values in params]
    settings["aliases"] = {alias.name: alias.doc for alias in DESIGN_ALIASES.get(task, ())}
    settings["designs"] = [{"design": d.slug, "values": d.values, "task_config": d.overrides} for d in designs]
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / SETTINGS_FILE, settings)
    rows: list[dict[str, Any]] = []
    outcomes: list[DesignOutcome] = []
    failed: list[dict[str, Any]] = []
    results = summarize(settings, rows, outcomes, counts, seed=seed, bootstrap=bootstrap, subsets=subsets)
    for number, design in enumerate(designs, start=1):
        started = time.perf_counter()
        directory = out / DESIGNS_DIR / design.slug
        finished = (directory / SCORES_FILE).is_file()
        prefix = f"sweep [{number}/{len(designs)}] {design.label}"
        try:
            _generate(task, design, directory, settings, progress=progress)
            analyze(directory, analyzer, seed=seed, workers=workers, progress=progress)
        except EnergyMarginError as error:
            # A design whose roll-outs cannot be generated or analysed (e.g. a blade angle that
            # drives the boxes into the gripper) is reported as such; the sweep goes on.
            failed.append(failed_row(design, directory, str(error)))
            say(f"{prefix}: not analysed: {error}")
        else:
            outcome = design_outcome(load_dataset(directory), load_scores(directory))
            row = design_row(design, outcome)
            rows.append(row)
            outcomes.append(outcome)
            say(
                f"{prefix}: success {row['successes']}/{row['trajectories']} "
                f"[{row['success_rate_low']:.2f}, {row['success_rate_high']:.2f}], early success score "
                f"{row['early_success_score']:.4f}, capture score {row['capture_score']:.4f} "
                + ("(already analysed)" if finished else f"({time.perf_counter() - started:.0f} s)")
            )
        results = summarize(settings, rows, outcomes, counts, seed=seed, bootstrap=bootstrap, subsets=subsets)
        results["failed"] = failed
        write_results(out, results)
    return results


def failed_row(design: Design, directory: Path, error: str) -> dict[str, Any]:
    """The row of a design that was not analysed: its values, the labels' success rate if generated, the error."""
    row: dict[str, Any] = {"design": design.slug, **design.values}
    try:
        success = load_dataset(directory).success_labels()
    except EnergyMarginError:
        success = None
    if success is not None:
        low, high = wilson_interval(int(success.sum()), int(success.size))
        row.update(
            trajectories=int(success.size),
            successes=int(success.sum()),
            success_rate=float(success.mean()),
            success_rate_low=low,
            success_rate_high=high,
        )
    row["error"] = error
    return row


def _objects(task: Task, n_objects: int | None) -> int:
    """The objects per scene of a sweep of ``task``, checked before anything is written."""
    if task.fixed_objects is not None:
        if n_objects is not None and n_objects != task.fixed_objects:
            raise EnergyMarginError(f"{task.label} has {task.fixed_objects} objects; --objects {n_objects} differs")
        return task.fixed_objects
    if n_objects is None:
        raise EnergyMarginError(f"{task.label} needs the number of objects (--objects)")
    _check_int("objects", n_objects, 1)
    return int(n_objects)


def _generate(task: str, design: Design, directory: Path, settings: dict[str, Any], *, progress: bool) -> Dataset:
    bar = None
    if progress and not (directory / SCORES_FILE).is_file():
        from tqdm import tqdm

        bar = tqdm(total=settings["n_trajectories"], unit="traj", desc="generate", dynamic_ncols=True)
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
            progress=bar.update if bar is not None else None,
        )
    finally:
        if bar is not None:
            bar.close()


def summarize(
    settings: dict[str, Any],
    rows: list[dict[str, Any]],
    outcomes: Sequence[DesignOutcome],
    counts: Sequence[int],
    *,
    seed: int,
    bootstrap: int,
    subsets: int,
) -> dict[str, Any]:
    """The results of the designs analysed so far (correlations once two designs are in)."""
    results: dict[str, Any] = {"settings": settings, "rows": rows}
    if len(outcomes) >= 2:
        results["correlations"] = rank_correlations(outcomes, seed=seed, bootstrap=bootstrap)
        results["convergence"] = rank_convergence(outcomes, counts, subsets=subsets, seed=seed)
    results["trajectories"] = {
        row["design"]: {
            "success": outcome.success.astype(int).tolist(),
            **{name: outcome.column(name).tolist() for name in MARGINS},
        }
        for row, outcome in zip(rows, outcomes, strict=True)
    }
    return results


def table_fields(results: dict[str, Any]) -> list[str]:
    """The CSV columns: design, the swept parameters, then the measured values."""
    names = [param["name"] for param in results["settings"]["params"]]
    measured = ["trajectories", "successes", "success_rate", "success_rate_low", "success_rate_high"]
    return ["design", *names, *measured, *MARGINS, "runtime_per_frame_s", "error"]


def write_results(out: Path, results: dict[str, Any]) -> list[Path]:
    """Write ``results.csv``, ``results.json`` and (with matplotlib) ``results.png`` in ``out``."""
    fields = table_fields(results)
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=fields, lineterminator="\n")
    writer.writeheader()
    for row in [*results["rows"], *results.get("failed", [])]:
        cells = {key: row.get(key, "") for key in fields}
        writer.writerow({key: json.dumps(value) if isinstance(value, list) else value for key, value in cells.items()})
    csv_path = out / RESULTS_FILE
    atomic_write_text(csv_path, buffer.getvalue())
    json_path = csv_path.with_suffix(".json")
    write_json(json_path, results)
    written = [csv_path, json_path]
    if "correlations" in results:
        png = plot(results, csv_path.with_suffix(".png"))
        if png is not None:
            written.append(png)
    return written


def plot(results: dict[str, Any], path: Path) -> Path | None:
    """Success rate against the early margin per design, and rho against t; ``None`` without matplotlib."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    rows = results["rows"]
    settings = results["settings"]
    names = [param["name"] for param in settings["params"]]
    figure, (left, right) = plt.subplots(1, 2, figsize=(11.0, 4.2))
    x = np.array([row["early_success_score"] for row in rows])
    y = np.array([row["success_rate"] for row in rows])
    error = np.array(
        [
            [r["success_rate"] - r["success_rate_low"] for r in rows],
            [r["success_rate_high"] - r["success_rate"] for r in rows],
        ]
    )
    left.errorbar(x, y, yerr=error, fmt="o", capsize=3)
    for index, (row, xi, yi) in enumerate(zip(rows, x, y, strict=True)):
        text = ", ".join(json.dumps(row[name]) for name in names)
        # Alternate above and below so that neighbouring designs' labels do not overlap.
        offset = (4, 4) if index % 2 == 0 else (4, -10)
        left.annotate(text, (xi, yi), textcoords="offset points", xytext=offset, fontsize=7)
    early = results["correlations"]["early_success_score"]
    rho = "n/a" if early["rho"] is None else f"{early['rho']:.2f}"
    p_value = "" if early["p_value"] is None else f", p = {early['p_value']:.3f}"
    left.set_title(f"Spearman rho = {rho}{p_value} ({len(rows)} designs)", fontsize=10)
    left.set_xlabel(f"mean {MARGIN_LABELS['early_success_score']}")
    left.set_ylabel(f"success rate over {settings['n_trajectories']} trajectories (95 % Wilson)")
    left.set_ylim(-0.05, 1.05)
    left.grid(True, alpha=0.3)
    convergence = results["convergence"]
    counts = [row["trajectories"] for row in convergence]
    for name in (*MARGINS, "success_rate"):
        values = [np.nan if row[name] is None else row[name] for row in convergence]
        label = MARGIN_LABELS.get(name, f"success rate of t trajectories ({', '.join(names)})")
        if name == "success_rate":
            label = "success rate of t trajectories"
        right.plot(counts, values, marker="o", linestyle="--" if name == "success_rate" else "-", label=label)
    right.set_xscale("log")
    right.set_xticks(counts, [str(count) for count in counts])
    right.minorticks_off()
    right.set_xlabel("trajectories t per design")
    right.set_ylabel(f"mean Spearman rho vs success rate of all {settings['n_trajectories']}")
    shown = [row[name] for row in convergence for name in (*MARGINS, "success_rate") if row[name] is not None]
    right.set_ylim(max(-1.05, min(shown, default=0.0) - 0.05), 1.02)
    right.grid(True, alpha=0.3)
    right.legend(fontsize=8, loc="lower right")
    objects = "" if settings["n_objects"] is None else f", n_o = {settings['n_objects']}"
    figure.suptitle(
        f"{settings['task']} design sweep over {', '.join(names)}{objects}, "
        f"{settings['n_trajectories']} x {settings['n_frames']} frames per design",
        fontsize=11,
    )
    figure.tight_layout()
    figure.savefig(path, dpi=120)
    plt.close(figure)
    return path


def _fmt(value: float | None, digits: int = 3) -> str:
    return "n/a" if value is None else f"{value:.{digits}f}"


def format_table(results: dict[str, Any]) -> str:
    """The design table, the rank correlations and the convergence table as text."""
    names = [param["name"] for param in results["settings"]["params"]]
    widths = [max(len(name), 8) for name in names]
    header = (
        " ".join(f"{name:>{width}s}" for name, width in zip(names, widths, strict=True))
        + f" {'success':>8s} {'rate [95 % Wilson]':>20s} {'early succ':>10s} {'succ score':>10s}"
        + f" {'capture':>8s} {'s/frame':>8s}"
    )
    lines = [header, "-" * len(header)]
    for row in results["rows"]:
        cells = " ".join(f"{json.dumps(row[name]):>{width}s}" for name, width in zip(names, widths, strict=True))
        rate = f"{row['success_rate']:.2f} [{row['success_rate_low']:.2f}, {row['success_rate_high']:.2f}]"
        lines.append(
            f"{cells} {row['successes']:>4d}/{row['trajectories']:<3d} {rate:>20s} {row['early_success_score']:10.4f}"
            f" {row['success_score']:10.4f} {row['capture_score']:8.4f} {row['runtime_per_frame_s']:8.3f}"
        )
    for row in results.get("failed", []):
        cells = " ".join(f"{json.dumps(row[name]):>{width}s}" for name, width in zip(names, widths, strict=True))
        rate = "" if "successes" not in row else f" (labels: {row['successes']}/{row['trajectories']} successful)"
        lines.append(f"{cells} not analysed{rate}: {row['error']}")
    correlations = results.get("correlations")
    if correlations:
        lines.append("")
        lines.append(f"Spearman rank correlation with the success rate ({len(results['rows'])} designs):")
        for name in MARGINS:
            entry = correlations[name]
            kind = "exact" if entry["exact"] else "permutation"
            interval = (
                "" if entry["low"] is None else f", 95 % trajectory bootstrap [{entry['low']:.2f}, {entry['high']:.2f}]"
            )
            p_value = "" if entry["p_value"] is None else f", p = {entry['p_value']:.3f} ({kind})"
            lines.append(f"  {MARGIN_LABELS[name]:>34s}: rho = {_fmt(entry['rho'], 2)}{p_value}{interval}")
        lines.append("")
        lines.append("mean rho against the success rate of all trajectories, from t trajectories per design:")
        lines.append(f"  {'t':>4s} {'early succ':>10s} {'succ score':>10s} {'capture':>8s} {'succ rate':>10s}")
        for row in results["convergence"]:
            lines.append(
                f"  {row['trajectories']:>4d} {_fmt(row['early_success_score'], 2):>10s} "
                f"{_fmt(row['success_score'], 2):>10s} {_fmt(row['capture_score'], 2):>8s} "
                f"{_fmt(row['success_rate'], 2):>10s}"
            )
    return "\n".join(lines)
