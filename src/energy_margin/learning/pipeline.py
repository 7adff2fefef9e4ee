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

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.run import analyze
from energy_margin.data.dataset import METADATA_FILE
from energy_margin.data.generate import check_engine, generate_dataset
from energy_margin.data.scores_file import SCORES_FILE
from energy_margin.errors import EnergyMarginError, InvalidParameterError, check_choice, check_float, check_int
from energy_margin.learning.margin_model import KINDS, MarginModel, fit_margin_model, load_training_datasets
from energy_margin.runs import RunLockedError, RunSpec, open_run, progress_bar
from energy_margin.runs.files import atomic_path
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


@dataclass(frozen=True)
class LearnSet:
    """One generated and analysed dataset of the pipeline.

    Attributes:
        name: its folder under ``WORK/sets`` (``objects-10``, ``scene``).
        objects: objects per scene.
        directory: the dataset directory.
        generation_seed: the seed it was generated with.
        analysis_seed: the seed it was analysed with.
        generated: this call generated it (``False``: it was there from an earlier run).
        analysed: this call scored frames of it (``False``: its scores.csv was complete).

    """

    name: str
    objects: int
    directory: Path
    generation_seed: int
    analysis_seed: int
    generated: bool
    analysed: bool

    def to_dict(self) -> dict[str, Any]:
        """The set as JSON values."""
        return {
            "name": self.name,
            "objects": self.objects,
            "directory": str(self.directory),
            "generation_seed": self.generation_seed,
            "analysis_seed": self.analysis_seed,
            "generated": self.generated,
            "analysed": self.analysed,
        }


@dataclass(frozen=True)
class LearnResult:
    """What :func:`learn_pipeline` made.

    Attributes:
        model: the fitted model (also written to ``out`` and ``WORK/model.npz``).
        report: :func:`~energy_margin.learning.margin_model.fit_margin_model`'s report.
        out: the model file written.
        work: the work directory.
        sets: the datasets, in the order of ``objects``.
        fit_seed: the seed of the fit.
        resumed: the work directory held this very run before the call.
        seconds: wall time of the call.

    """

    model: MarginModel
    report: dict[str, Any]
    out: Path
    work: Path
    sets: tuple[LearnSet, ...]
    fit_seed: int
    resumed: bool
    seconds: float


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


def learn_pipeline(
    work: Path | str,
    out: Path | str,
    *,
    task: str | None = None,
    scene: str | os.PathLike[str] | None = None,
    objects: Sequence[int] | None = None,
    trajectories: int,
    frames: int = 10,
    seed: int = 0,
    workers: int = 1,
    iterations: int | None = None,
    kind: str = "set",
    holdout: float = 0.25,
    success_frames: int = 3,
    overwrite: bool = False,
    progress: bool = False,
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
        trajectories: trajectories per set, >= 2 (the fit holds some out).
        frames: frames per trajectory, >= 1.
        seed: the seed every other seed is derived from (module docstring).
        workers: analysis worker processes, >= 1; the results do not depend on it.
        iterations: expansions per frame of the analysis (default the analyzer's, 300).
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
    check_int("trajectories", trajectories, minimum=2)
    check_int("frames", frames, minimum=1)
    check_int("seed", seed, minimum=0)
    check_int("workers", workers, minimum=1)
    if iterations is not None:
        check_int("iterations", iterations, minimum=1)
    check_choice("kind", kind, KINDS)
    check_float("holdout", holdout, minimum=0.0, maximum=1.0, exclusive_minimum=True, exclusive_maximum=True)
    check_int("success_frames", success_frames, minimum=1)
    resolved, config, sets = _task_and_sets(task, scene, objects)
    analyzer = AnalyzerConfig() if iterations is None else AnalyzerConfig(iterations=iterations)
    check_engine(resolved, analyzer.engine)
    work, out = Path(work), Path(out)
    _check_out(out, work, overwrite=overwrite)
    fit_seed, seeds = pipeline_seeds(seed, len(sets))
    settings: dict[str, Any] = {
        "task": resolved.name,
        "task_config": resolved.config.to_dict(),
        "scene_file": config.get("scene_file"),
        "objects": [count for _, count in sets],
        "trajectories": trajectories,
        "frames": frames,
        "seed": seed,
        "analyzer": analyzer.to_dict(),
        "sets": [
            {"name": name, "objects": count, "generation_seed": generation, "analysis_seed": analysis}
            for (name, count), (generation, analysis) in zip(sets, seeds, strict=True)
        ],
        "fit_seed": fit_seed,
        "kind": kind,
        "holdout": holdout,
        "success_frames": success_frames,
        "regressor": options,
        "workers": workers,
    }
    say = log if log is not None else (lambda line: print(line, file=sys.stderr, flush=True))
    try:
        run = open_run(work, LEARN_RUN, settings, overwrite=overwrite, engine=analyzer.engine)
    except EnergyMarginError as error:
        # The run layer names `out`, the directory of most commands; here it is `work`.
        message = str(error).replace("choose another `out`", "choose another `work`")
        raise (RunLockedError if isinstance(error, RunLockedError) else EnergyMarginError)(message) from None
    with run:
        if run.resumed:
            say(f"learn: resuming {work} (what is generated and analysed there is kept)")
        (work / SETS_DIR).mkdir(exist_ok=True)
        done: list[LearnSet] = []
        for number, ((name, count), (generation, analysis)) in enumerate(zip(sets, seeds, strict=True), start=1):
            prefix = f"learn [{number}/{len(sets)}] {name}"
            directory = work / SETS_DIR / name
            made = _generate(resolved.name, config, directory, count, trajectories, frames, generation, progress)
            state = "generated" if made else "already generated"
            say(f"{prefix}: {state} {trajectories} trajectories x {frames} frames")
            scored = not (directory / SCORES_FILE).is_file()
            tick = time.perf_counter()
            analyze(directory, analyzer, seed=analysis, workers=workers, progress=progress)
            say(f"{prefix}: " + (f"analysed ({time.perf_counter() - tick:.0f} s)" if scored else "already analysed"))
            done.append(LearnSet(name, count, directory, generation, analysis, made, scored))
        say(f"learn: fitting a {kind} margin on {len(done)} set{'s' if len(done) > 1 else ''}")
        datasets = load_training_datasets([item.directory for item in done])
        model, report = fit_margin_model(
            datasets, seed=fit_seed, kind=kind, holdout=holdout, success_frames=success_frames, **options
        )
        model.save(work / MODEL_FILE)
        _copy(work / MODEL_FILE, out)
    return LearnResult(
        model=model,
        report=report,
        out=out,
        work=work,
        sets=tuple(done),
        fit_seed=fit_seed,
        resumed=run.resumed,
        seconds=time.perf_counter() - started,
    )


def _generate(
    task: str,
    config: dict[str, Any],
    directory: Path,
    objects: int,
    trajectories: int,
    frames: int,
    seed: int,
    progress: bool,
) -> bool:
    """Generate the set in ``directory`` unless it is there; whether it was generated now."""
    there = (directory / METADATA_FILE).is_file()
    bar = progress_bar(trajectories, desc=f"generate {directory.name}", unit="traj", enabled=progress and not there)
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
