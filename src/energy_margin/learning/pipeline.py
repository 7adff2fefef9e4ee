"""Generate, analyse and fit in one resumable run: the ``--task`` / ``--scene`` form of ``energy-margin learn``.

:func:`learn_pipeline` generates one dataset per number of objects of a task (or one of a scene
file) with :func:`~energy_margin.data.generate.generate_dataset`, scores every frame of each with
:func:`~energy_margin.analysis.run.analyze`, fits a learned margin to all of them with
:func:`~energy_margin.learning.margin_model.fit_margin_model` and writes it to ``out``.

The work directory is a run of the run layer (:func:`energy_margin.runs.open_run`), locked while
the pipeline runs::

    WORK/learn.json              the resolved settings, written first
    WORK/sets/<name>/            one dataset per set (``objects-<n>``, or ``scene``), its
                                 analysis.json, scores journal and scores.csv beside it
    WORK/model.npz               the last model fitted (copied to ``out``)

A rerun with the same settings resumes: a set already generated is kept (``generate_dataset``
returns the dataset it finds), an analysis resumes from its journal (``analyze`` does), and the fit
runs again at the end (it takes seconds). A rerun with other settings is refused in one line
naming the first differing setting, unless ``overwrite``, which removes the files above and
nothing else. The fit's own settings (``kind``, ``holdout``, ``success_frames``, the regressor's
options) and ``workers`` decide nothing kept in the work directory, so they may change between
runs: the datasets and their scores are reused and only the fit differs.

Seeds: ``children = numpy.random.SeedSequence(seed).spawn(1 + n_sets)``. ``children[0]`` gives the
fit's seed (the held-out split and the regressor); set ``i`` (in the order of ``objects``) has
``children[1 + i]``, whose two children ``children[1 + i].spawn(2)`` give its generation seed and
its analysis seed. Each seed is the child's ``generate_state(1, numpy.uint32)[0]`` (scikit-learn
takes seeds below 2**32). A set's seeds depend on its position and ``seed`` only, not on how many
sets follow it. The analysis gives every frame its own seed from the set's analysis seed
(:mod:`energy_margin.analysis.run`), so the scores, and the model, do not depend on ``workers``.
"""

from __future__ import annotations

import filecmp
import os
import shutil
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin._renamed import renamed_keyword
from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.run import analyze
from energy_margin.data.dataset import METADATA_FILE
from energy_margin.data.generate import check_engine, generate_dataset
from energy_margin.data.scores_file import SCORES_FILE
from energy_margin.errors import EnergyMarginError, InvalidParameterError, check_choice, check_float, check_int
from energy_margin.learning.margin_model import (
    DEFAULT_KIND,
    KINDS,
    MarginModel,
    MarginModelReport,
    fit_margin_model,
    load_training_datasets,
)
from energy_margin.learning.pipeline_results import LearnResult, LearnSet
from energy_margin.runs import RunDirectory, RunLockedError, RunSpec, open_run, progress_bar
from energy_margin.runs.files import atomic_path
from energy_margin.runs.progress import Progress
from energy_margin.tasks import Task, get_task

__all__ = [
    "LEARN_RUN",
    "MODEL_FILE",
    "SETS_DIR",
    "SETTINGS_FILE",
    "LearnResult",
    "LearnSet",
    "learn_pipeline",
    "pipeline_seeds",
]

#: The pipeline's settings file, written first in the work directory.
SETTINGS_FILE = "learn.json"
#: The folder of the generated and analysed datasets.
SETS_DIR = "sets"
#: The last model fitted in the work directory (the one copied to ``out``).
MODEL_FILE = "model.npz"
#: The settings that decide the datasets and their scores, in the order a refusal names them first.
RESUME_KEYS = ("task", "task_config", "scene_file", "objects", "trajectories", "frames", "seed", "analyzer", "sets")
#: Settings that decide nothing kept in the work directory: they may change on a rerun.
FIT_SETTINGS = ("kind", "holdout", "success_frames", "regressor", "workers", "fit_seed")
#: The work directory of a pipeline: its settings, the sets and the last model.
LEARN_RUN = RunSpec(
    contents="a learning pipeline",
    settings_file=SETTINGS_FILE,
    outputs=(SETS_DIR, MODEL_FILE),
    compared=RESUME_KEYS,
    may_differ=FIT_SETTINGS,
)


def _seed(sequence: np.random.SeedSequence) -> int:
    return int(sequence.generate_state(1, np.uint32)[0])


def pipeline_seeds(seed: int, n_sets: int) -> tuple[int, list[tuple[int, int]]]:
    """The fit seed and each set's (generation, analysis) seeds of a pipeline run with ``seed``.

    ``children = SeedSequence(seed).spawn(1 + n_sets)``: the fit seed from ``children[0]``, set
    ``i``'s two seeds from ``children[1 + i].spawn(2)``; each seed is the child's first
    ``uint32`` state word.
    """
    children = np.random.SeedSequence(seed).spawn(1 + n_sets)
    sets = []
    for child in children[1:]:
        generation, analysis = child.spawn(2)
        sets.append((_seed(generation), _seed(analysis)))
    return _seed(children[0]), sets


def _task_and_sets(
    task: str | None, scene: str | os.PathLike[str] | None, objects: Sequence[int] | None
) -> tuple[Task, dict[str, Any], list[tuple[str, int]]]:
    """The task, its generation configuration and the (name, objects) of every set; checked."""
    if (task is None) == (scene is None):
        raise EnergyMarginError("give a task or a scene file (exactly one)")
    if scene is not None:
        if objects is not None:
            raise InvalidParameterError("objects", f"does not apply to `scene={scene}`: a scene file fixes its objects")
        path = Path(scene)
        if not path.is_file():
            raise EnergyMarginError(f"scene file {scene} does not exist")
        config: dict[str, Any] = {"scene_file": os.path.abspath(path)}
        resolved = get_task("scene", config)
        return resolved, config, [("scene", resolved.default_objects)]
    assert task is not None
    resolved = get_task(task)
    counts = [resolved.default_objects] if objects is None else list(objects)
    if not counts:
        raise InvalidParameterError("objects", "must list at least one number of objects")
    for count in counts:
        check_int("objects", count, minimum=1)
        if resolved.fixed_objects is not None and count != resolved.fixed_objects:
            raise EnergyMarginError(f"{resolved.label} has {resolved.fixed_objects} objects; `objects={count}` differs")
    repeated = sorted({count for count in counts if counts.count(count) > 1})
    if repeated:
        raise InvalidParameterError("objects", f"must be distinct, got {repeated[0]} twice")
    return resolved, {}, [(f"objects-{count}", int(count)) for count in counts]


def _check_out(out: Path, work: Path, *, overwrite: bool) -> None:
    """Refuse an ``out`` that is a folder, or a file not written by this work directory (without ``overwrite``)."""
    if out.is_dir():
        raise InvalidParameterError("out", f"{out} is a directory; give a model file name, e.g. model.npz")
    if not out.exists() or overwrite:
        return
    ours = work / MODEL_FILE
    if ours.is_file() and (_same_file(out, ours) or filecmp.cmp(out, ours, shallow=False)):
        return  # the model an earlier run of this work directory wrote: replaced by the new fit
    raise EnergyMarginError(f"{out} already exists; pass `overwrite=True` to replace it")


def _same_file(a: Path, b: Path) -> bool:
    try:
        return a.resolve() == b.resolve()
    except OSError:
        return False


@renamed_keyword(trajectories="n_trajectories", frames="n_frames", iterations="expansions")
def learn_pipeline(
    work: Path | str,
    out: Path | str,
    *,
    task: str | None = None,
    scene: str | os.PathLike[str] | None = None,
    objects: Sequence[int] | None = None,
    n_trajectories: int,
    n_frames: int = 10,
    seed: int = 0,
    workers: int = 1,
    expansions: int | None = None,
    kind: str = DEFAULT_KIND,
    holdout: float = 0.25,
    success_frames: int = 3,
    overwrite: bool = False,
    progress: Progress = False,
    log: Callable[[str], None] | None = None,
    **options: Any,
) -> LearnResult:
    """Generate, analyse and fit (or resume doing so) in ``work``; write the model to ``out``.

    Every argument is checked, and ``out`` too, before anything is written.

    Args:
        work: the work directory (created), a run: locked, its settings written first.
        out: the model file to write (``.npz``).
        task: a registered task (or ``scene``; exactly one).
        scene: a scene file (docs/howto/scenes.md): one set of its objects.
        objects: objects per scene, one set per entry, distinct, each >= 1 (``task`` only;
            default the task's typical number).
        n_trajectories: trajectories per set, >= 2 (the fit holds some out).
        n_frames: frames per trajectory, >= 1.
        seed: the seed every other seed is derived from (module docstring).
        workers: analysis worker processes, >= 1; the results do not depend on it.
        expansions: expansions per frame of the analysis (default the analyzer's, 300).
        kind: regressor, one of :data:`~energy_margin.learning.margin_model.KINDS`.
        holdout: fraction of the trajectories held out for the report, in (0, 1).
        success_frames: k-bar of the report's trajectory success AP, >= 1.
        overwrite: replace a run of other settings in ``work`` and an ``out`` not written by
            ``work`` instead of refusing.
        progress: generation and analysis progress bars on standard error.
        log: receives one line per step (standard error by default).
        options: the regressor's settings (:func:`energy_margin.learning.regressors.fit_regressor`).

    Returns:
        The model, its report and the sets.

    Raises:
        EnergyMarginError: a bad argument (:class:`~energy_margin.errors.InvalidParameterError`
            for a bad number), ``work`` holding another run or being written by a live process,
            or ``out`` existing.

    """
    started = time.perf_counter()
    counts = (n_trajectories, n_frames, seed, workers, expansions, success_frames)
    plan = _plan(task, scene, objects, counts, kind=kind, holdout=holdout, options=options, progress=progress)
    work, out = Path(work), Path(out)
    _check_out(out, work, overwrite=overwrite)
    say = log if log is not None else (lambda line: print(line, file=sys.stderr, flush=True))
    with _open_learn_run(work, plan.settings(), overwrite=overwrite, engine=plan.analyzer.engine) as run:
        if run.resumed:
            say(f"learn: resuming {work} (what is generated and analysed there is kept)")
        (work / SETS_DIR).mkdir(exist_ok=True)
        done = [_prepare_set(plan, work, index, say) for index in range(len(plan.sets))]
        model, report = _fit(plan, done, work, out, say)
    return LearnResult(
        model=model,
        report=report,
        out=out,
        work=work,
        sets=tuple(done),
        fit_seed=plan.fit_seed,
        resumed=run.resumed,
        seconds=time.perf_counter() - started,
    )


@dataclass(frozen=True)
class _Plan:
    """What a learn run does, checked: the task, the sets with their (generation, analysis) seeds, the fit.

    The counts are :func:`learn_pipeline`'s arguments of the same names.
    """

    task: Task
    config: dict[str, Any]
    sets: list[tuple[str, int]]
    seeds: list[tuple[int, int]]
    fit_seed: int
    analyzer: AnalyzerConfig
    trajectories: int
    frames: int
    seed: int
    workers: int
    kind: str
    holdout: float
    success_frames: int
    options: dict[str, Any]
    progress: Progress

    def settings(self) -> dict[str, Any]:
        """The run's settings (``learn.json``)."""
        return {
            "task": self.task.name,
            "task_config": self.task.config.to_dict(),
            "scene_file": self.config.get("scene_file"),
            "objects": [count for _, count in self.sets],
            "trajectories": self.trajectories,
            "frames": self.frames,
            "seed": self.seed,
            "analyzer": self.analyzer.to_dict(),
            "sets": [
                {"name": name, "objects": count, "generation_seed": generation, "analysis_seed": analysis}
                for (name, count), (generation, analysis) in zip(self.sets, self.seeds, strict=True)
            ],
            "fit_seed": self.fit_seed,
            "kind": self.kind,
            "holdout": self.holdout,
            "success_frames": self.success_frames,
            "regressor": self.options,
            "workers": self.workers,
        }


def _plan(
    task: str | None,
    scene: str | os.PathLike[str] | None,
    objects: Sequence[int] | None,
    counts: tuple[int, int, int, int, int | None, int],
    *,
    kind: str,
    holdout: float,
    options: dict[str, Any],
    progress: Progress,
) -> _Plan:
    """Check the arguments, resolve the task and its sets, derive the seeds (:func:`learn_pipeline`).

    ``counts`` holds ``(n_trajectories, n_frames, seed, workers, expansions, success_frames)``.
    """
    trajectories, frames, seed, workers, expansions, success_frames = counts
    check_int("n_trajectories", trajectories, minimum=2)
    check_int("n_frames", frames, minimum=1)
    check_int("seed", seed, minimum=0)
    check_int("workers", workers, minimum=1)
    if expansions is not None:
        check_int("expansions", expansions, minimum=1)
    check_choice("kind", kind, KINDS)
    check_float("holdout", holdout, minimum=0.0, maximum=1.0, exclusive_minimum=True, exclusive_maximum=True)
    check_int("success_frames", success_frames, minimum=1)
    resolved, config, sets = _task_and_sets(task, scene, objects)
    analyzer = (AnalyzerConfig() if expansions is None else AnalyzerConfig(expansions=expansions)).fixed_continuation()
    check_engine(resolved, analyzer.engine)
    fit_seed, seeds = pipeline_seeds(seed, len(sets))
    return _Plan(
        resolved, config, sets, seeds, fit_seed, analyzer, trajectories, frames, seed, workers, kind, holdout,
        success_frames, options, progress,
    )  # fmt: skip


def _open_learn_run(work: Path, settings: dict[str, Any], *, overwrite: bool, engine: str) -> RunDirectory:
    """The locked learn run in ``work``; its errors name ``work`` (the run layer says ``out``)."""
    try:
        return open_run(work, LEARN_RUN, settings, overwrite=overwrite, engine=engine)
    except EnergyMarginError as error:
        # The run layer names `out`, the directory of most commands; here it is `work`.
        message = str(error).replace("choose another `out`", "choose another `work`")
        raise (RunLockedError if isinstance(error, RunLockedError) else EnergyMarginError)(message) from None


def _prepare_set(plan: _Plan, work: Path, index: int, say: Callable[[str], None]) -> LearnSet:
    """Generate and analyse set ``index`` of the plan in ``work`` (or keep what is there), saying so."""
    (name, count), (generation, analysis) = plan.sets[index], plan.seeds[index]
    prefix = f"learn [{index + 1}/{len(plan.sets)}] {name}"
    directory = work / SETS_DIR / name
    made = _generate(
        plan.task.name, plan.config, directory, count, plan.trajectories, plan.frames, generation, plan.progress
    )
    state = "generated" if made else "already generated"
    say(f"{prefix}: {state} {plan.trajectories} trajectories x {plan.frames} frames")
    scored = not (directory / SCORES_FILE).is_file()
    tick = time.perf_counter()
    analyze(directory, plan.analyzer, seed=analysis, workers=plan.workers, progress=plan.progress)
    say(f"{prefix}: " + (f"analysed ({time.perf_counter() - tick:.0f} s)" if scored else "already analysed"))
    return LearnSet(name, count, directory, generation, analysis, made, scored)


def _fit(
    plan: _Plan, done: list[LearnSet], work: Path, out: Path, say: Callable[[str], None]
) -> tuple[MarginModel, MarginModelReport]:
    """Fit the plan's model on the sets ``done``, save it in ``work`` and copy it to ``out``; it and its report."""
    say(f"learn: fitting a {plan.kind} margin on {len(done)} set{'s' if len(done) > 1 else ''}")
    datasets = load_training_datasets([item.directory for item in done])
    model, report = fit_margin_model(
        datasets,
        seed=plan.fit_seed,
        kind=plan.kind,
        holdout=plan.holdout,
        success_frames=plan.success_frames,
        **plan.options,
    )
    model.save(work / MODEL_FILE)
    _copy(work / MODEL_FILE, out)
    return model, report


def _generate(
    task: str,
    config: dict[str, Any],
    directory: Path,
    objects: int,
    trajectories: int,
    frames: int,
    seed: int,
    progress: Progress,
) -> bool:
    """Generate the set in ``directory`` unless it is there; whether it was generated now."""
    there = (directory / METADATA_FILE).is_file()
    bar = progress_bar(
        trajectories, desc=f"generate {directory.name}", unit="traj", enabled=False if there else progress
    )
    try:
        generate_dataset(
            task,
            n_objects=objects,
            n_trajectories=trajectories,
            n_frames=frames,
            seed=seed,
            out=directory,
            task_config=config,
            progress=bar.update,
        )
    finally:
        bar.close()
    return not there


def _copy(source: Path, out: Path) -> None:
    """Copy the model file ``source`` to ``out`` atomically (nothing when they are one file)."""
    if _same_file(source, out):
        return
    out.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(out) as temporary:
        shutil.copyfile(source, temporary)
