"""Design search: black-box optimisation of a task's design by the energy margin, then verification.

``design_search`` searches the space of :mod:`~energy_margin.design.space` with an
optimiser of :mod:`~energy_margin.design.optimizers`. One evaluation of a design
generates T randomised roll-outs of F frames of it (``generate``), scores their frames (the tree of
``analyze`` at a budget of expansions, or a learned margin: the ``scorer``) and takes the mean over
the T trajectories of one score column (the success score by default). Every design is generated
and scored with the same seed: trajectory i of every design starts from the same draws and frame j
of it gets the same analysis seed (common random numbers), so designs differ by their setting, not
by luck.

After the search, the same objective is computed over the equal-cost grid (the even grid with as
many designs as the optimiser evaluated, at most) and for the task's own (default) design. The
verification then measures the real success rate of the chosen design (the search's best), the
default design and the grid's best, each over E closed-loop episodes per disturbance level
(``control``'s levels; the ``verifier``), with Wilson intervals; with ``verify_all`` every visited
design too, and Spearman's rho between the objective and the verified success rate over the
verified designs.

The verifier and the scorer are given by the caller (:class:`Scorer`, :class:`Verifier`): the
tree scorer lives here (:class:`TreeScorer`), the learned one in
:mod:`energy_margin.learning.scoring` and the episode verifier in
:mod:`energy_margin.design.verification`, stages after this one.

Layout of the output directory, a run directory (:func:`~energy_margin.runs.open_run`)::

    DIR/design.json              the resolved settings, written first (checked again on resume)
    DIR/evaluations/<design>/    each distinct evaluated design's roll-outs and scores
    DIR/evaluations.jsonl        journal: one line per evaluation (search, grid, default)
    DIR/verification.jsonl       journal: one line per verification episode
    DIR/result.json, result.csv  the verified designs (the JSON holds everything); evaluations.csv
    DIR/search.png, tool.png     the figure of the search and the picture of the chosen design

A rerun with the same settings replays the optimiser with the journal's objectives (the same
points, checked) and goes on where it stopped; the results do not depend on ``workers``.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from energy_margin.design.optimizers import OPTIMIZERS, require_optimizer
from energy_margin.design.rank import MARGINS
from energy_margin.design.scorers import DESIGN_FRAMES, DESIGN_TRAJECTORIES, Scorer, TreeScorer, Verifier
from energy_margin.design.search_result import (
    DesignSearchResult,
    format_result,
)
from energy_margin.design.search_run import (
    DEFAULT_LEVELS,
    EVALUATIONS_CSV,
    EVALUATIONS_DIR,
    EVALUATIONS_JOURNAL,
    FIGURE_FILE,
    PICTURE_FILE,
    RESULT_CSV,
    RESULT_JSON,
    SETTINGS_FILE,
    VERIFICATION_JOURNAL,
    DesignSearchRun,
    directory_name,
)
from energy_margin.design.space import (
    check_models,
    compile_design,
    default_design,
    grid_counts,
    parameter_dict,
    resolve_space,
)
from energy_margin.design.sweep import task_settings
from energy_margin.errors import InvalidParameterError, check_choice, check_int, check_seed
from energy_margin.runs import RunDirectory, RunSpec, run_directory
from energy_margin.runs.progress import Progress
from energy_margin.runs.tables import write_json
from energy_margin.tasks import DesignParameter, Task, resolve_task

#: A design search's run directory. Every setting decides the results but the learned model's
#: path (its contents, by SHA-256, do).
DESIGN_RUN = RunSpec(
    contents="a design search",
    settings_file=SETTINGS_FILE,
    outputs=(
        EVALUATIONS_DIR,
        EVALUATIONS_JOURNAL,
        VERIFICATION_JOURNAL,
        RESULT_JSON,
        RESULT_CSV,
        EVALUATIONS_CSV,
        FIGURE_FILE,
        PICTURE_FILE,
    ),
    may_differ=("model_path",),
)


# The entry point ----------------------------------------------------------------------------------


def design_search(
    task: str | Task,
    params: Sequence[tuple[str, tuple[float, float] | list[Any]]] = (),
    *,
    optimizer: str = "tpe",
    evaluations: int,
    verify: int,
    out: Path | str,
    n_objects: int | None = None,
    n_trajectories: int = DESIGN_TRAJECTORIES,
    n_frames: int = DESIGN_FRAMES,
    seed: int = 0,
    score: str = "success_score",
    scorer: Scorer | None = None,
    verifier: Verifier | None = None,
    disturbances: Sequence[str] = DEFAULT_LEVELS,
    verify_all: bool = False,
    engine: str = "mujoco",
    fixed: dict[str, Any] | None = None,
    workers: int = 1,
    overwrite: bool = False,
    progress: Progress = False,
    log: Callable[[str], None] | None = None,
    picture: Callable[[Path, Path], Path | None] | None = None,
    extra_settings: dict[str, Any] | None = None,
    on_evaluation: Callable[[str, int], None] | None = None,
) -> DesignSearchResult:
    """Search the design of ``task`` by its energy margin, verify the result; write and return it.

    Every argument is checked, and the models of the space's corners compiled, before anything
    is written; the search then holds the lock of ``out`` until it returns.

    Args:
        task: a registered task's name (``"scene"`` with ``fixed={"scene_file": ...}`` for a scene
            file), or a task object (:func:`~energy_margin.tasks.resolve_task`).
        params: ``(name, (low, high))`` or ``(name, [values])`` per axis
            (:func:`~energy_margin.design.params.parse_param`); empty: the
            task's tool family (:meth:`~energy_margin.tasks.base.Task.design_space`).
        optimizer: ``"cma"``, ``"tpe"`` or ``"grid"``.
        evaluations: the optimiser's evaluations N, >= 1 (the grid's at most N).
        verify: verification episodes E per design and disturbance level, >= 1.
        out: the run directory (a rerun with the same settings resumes it).
        n_objects: objects per scene (``None`` for a task that fixes them).
        n_trajectories: roll-outs T per evaluation, >= 1.
        n_frames: frames F per roll-out, >= 1.
        seed: generation and scoring seed of every design, the optimiser's seed and the
            verification episodes' (``SeedSequence(seed).spawn(verify)``).
        score: the score column whose mean over the T roll-outs is the objective
            (``success_score``, ``early_success_score`` or ``capture_score``).
        scorer: scores each design's frames (default :class:`TreeScorer` at
            :data:`~energy_margin.design.scorers.DESIGN_EXPANSIONS` expansions a frame, 100).
        verifier: runs the verification episodes (``None``: no verification).
        disturbances: the levels of the verification.
        verify_all: verify every visited design too (for the rank correlation).
        engine: physics engine of generation and analysis.
        fixed: configuration overrides of every design (``--set``).
        workers: worker processes of each design's analysis and of the episodes, >= 1.
        overwrite: replace a search of other settings in ``out`` (its own files only).
        progress: show progress bars on standard error.
        log: receives one line per evaluation (standard error by default).
        picture: ``picture(dataset_directory, path)`` draws the chosen design (``tool.png``).
        extra_settings: more entries of ``design.json`` (``model_path``).
        on_evaluation: called with ``(phase, index)`` after each new evaluation is journalled.

    Returns:
        The :class:`~energy_margin.design.search_result.DesignSearchResult`; its ``to_dict()`` is ``result.json``.

    Raises:
        EnergyMarginError: a bad argument, parameter, range, value or design (one line each),
            an optimiser whose library is missing, ``out`` holding something else.
    """
    _check_counts(evaluations, verify, n_trajectories, n_frames, seed, workers, score)
    prepared = _prepare(
        task, params, fixed, disturbances, optimizer, scorer, verifier, n_objects, engine, seed, n_trajectories
    )
    settings = prepared.settings(n_frames, optimizer, evaluations, score, verifier, verify, verify_all, extra_settings)
    with run_directory(out, DESIGN_RUN, settings, overwrite=overwrite, engine=engine) as run:
        return _run_search(run, prepared, verifier, workers, progress, log, on_evaluation, picture)


def _check_counts(
    evaluations: int, verify: int, n_trajectories: int, n_frames: int, seed: int, workers: int, score: str
) -> None:
    """Refuse a count out of range, a bad seed or an unknown score column (before the task is resolved)."""
    check_int("evaluations", evaluations, minimum=1)
    check_int("verify", verify, minimum=1)
    check_int("n_trajectories", n_trajectories, minimum=1)
    check_int("n_frames", n_frames, minimum=1)
    check_seed(seed)
    check_int("workers", workers, minimum=1)
    check_choice("score", score, MARGINS)


@dataclass(frozen=True)
class _Prepared:
    """A search's resolved task, space and scorer, checked (:func:`_prepare`), before its run directory opens.

    The other fields are :func:`design_search`'s arguments of the same names.
    """

    task: Task
    space: list[DesignParameter]
    fixed: dict[str, Any]
    levels: list[str]
    scorer: Scorer
    n_objects: int
    engine: str
    seed: int
    n_trajectories: int

    def settings(
        self,
        n_frames: int,
        optimizer: str,
        evaluations: int,
        score: str,
        verifier: Verifier | None,
        verify: int,
        verify_all: bool,
        extra_settings: dict[str, Any] | None,
    ) -> dict[str, Any]:
        """The contents of ``design.json`` (:func:`design_search`'s arguments of the same names)."""
        space = self.space
        used = evaluations if optimizer != "grid" else min(evaluations, math.prod(grid_counts(space, evaluations)))
        return {
            "task": self.task.name,
            "fixed": self.fixed,
            "n_objects": self.n_objects,
            "n_trajectories": self.n_trajectories,
            "n_frames": n_frames,
            "seed": self.seed,
            "engine": self.engine,
            "space": [parameter_dict(parameter) for parameter in space],
            "optimizer": optimizer,
            "evaluations": evaluations,
            "objective": {**self.scorer.settings(), "score": score},
            "grid": {"counts": grid_counts(space, used), "size": math.prod(grid_counts(space, used))},
            "verify": _verify_settings(verifier, verify, self.levels, verify_all=verify_all),
            **(extra_settings or {}),
        }


def _prepare(
    task: str | Task,
    params: Sequence[tuple[str, tuple[float, float] | list[Any]]],
    fixed: dict[str, Any] | None,
    disturbances: Sequence[str],
    optimizer: str,
    scorer: Scorer | None,
    verifier: Verifier | None,
    n_objects: int | None,
    engine: str,
    seed: int,
    n_trajectories: int,
) -> _Prepared:
    """Resolve the task and its space, check the optimiser, the verifier and the models of the corners."""
    levels = list(dict.fromkeys(disturbances))
    if not levels:
        raise InvalidParameterError("disturbances", "must name at least one disturbance level")
    fixed = dict(fixed or {})
    task = resolve_task(task, fixed)
    space = resolve_space(task, params, fixed=fixed)
    require_optimizer(optimizer, space)
    scorer = scorer if scorer is not None else TreeScorer()
    analyzer = scorer.analyzer if isinstance(scorer, TreeScorer) else None
    n_objects, analyzer = task_settings(task, n_objects, engine, analyzer)
    if isinstance(scorer, TreeScorer):
        scorer = TreeScorer(analyzer)
    if verifier is not None:
        verifier.check(task, levels, n_objects=n_objects)
    check_models(task, space, fixed, n_objects=n_objects, seed=seed, n_trajectories=n_trajectories)
    compile_design(
        task, default_design(task, space, fixed), n_objects=n_objects, seed=seed, n_trajectories=n_trajectories
    )
    return _Prepared(
        task=task,
        space=space,
        fixed=fixed,
        levels=levels,
        scorer=scorer,
        n_objects=n_objects,
        engine=engine,
        seed=seed,
        n_trajectories=n_trajectories,
    )


def _run_search(
    run: RunDirectory,
    prepared: _Prepared,
    verifier: Verifier | None,
    workers: int,
    progress: Progress,
    log: Callable[[str], None] | None,
    on_evaluation: Callable[[str, int], None] | None,
    picture: Callable[[Path, Path], Path | None] | None,
) -> DesignSearchResult:
    """Run the search in the open run directory ``run``, draw the chosen design; the result."""
    say = log if log is not None else (lambda line: print(line, file=sys.stderr, flush=True))
    search = DesignSearchRun(
        run.path,
        prepared.task,
        prepared.space,
        prepared.fixed,
        run.settings,
        prepared.scorer,
        verifier,
        workers,
        progress,
        say,
        on_evaluation,
    )
    result = search.run()
    if picture is not None and result["chosen"] is not None:
        _draw_chosen(run.path, result, picture)
    return DesignSearchResult.from_dict(result)


def _verify_settings(
    verifier: Verifier | None, episodes: int, levels: list[str], *, verify_all: bool
) -> dict[str, Any]:
    """The ``verify`` entry of ``design.json``: episodes, levels, whether every design, the verifier's own."""
    own = verifier.settings() if verifier is not None else {"policy": None}
    return {"episodes": episodes, "disturbances": levels, "all": bool(verify_all), **own}


def _draw_chosen(out: Path, result: dict[str, Any], picture: Callable[[Path, Path], Path | None]) -> None:
    """Draw the chosen design into ``tool.png`` and say so in ``result.json``."""
    written = picture(out / EVALUATIONS_DIR / directory_name(result["chosen"]["design"]), out / PICTURE_FILE)
    if written is not None:
        result["picture"] = PICTURE_FILE
        write_json(out / RESULT_JSON, result)


__all__ = [
    "DEFAULT_LEVELS",
    "DESIGN_RUN",
    "OPTIMIZERS",
    "PICTURE_FILE",
    "RESULT_JSON",
    "SETTINGS_FILE",
    "DesignSearchResult",
    "Scorer",
    "TreeScorer",
    "Verifier",
    "design_search",
    "format_result",
]
