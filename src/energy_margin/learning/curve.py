"""Learning curves of a learned margin: held-out AP against the number of analysed frames.

A learned margin (:mod:`energy_margin.learning.margin_model`) is fitted to the tree's scores of
analysed frames, and every analysed frame costs one tree. :func:`learning_curve` measures how many
such frames a margin needs to reach its Average Precision, with the frames to analyse chosen at
random or by *active selection*.

The protocol is pool-based and simulated:

* The datasets are fully analysed already (``scores.csv``): every frame's tree scores are known,
  but a frame's scores are *revealed* to the learner only once the frame is selected, as if its
  tree were grown then. A curve point of size ``n`` is a fit on exactly ``n`` selected frames, so
  ``n`` is the number of trees grown; the frame, not the trajectory, is the unit.
* Whole trajectories are held out first, by the rule of
  :func:`~energy_margin.learning.margin_model.fit_margin_model` (reimplemented here as
  :func:`held_out_trajectories`): with ``groups`` every ``(dataset, trajectory)`` pair in order,
  the first ``min(len(groups) - 1, max(1, round(holdout * len(groups))))`` entries of
  ``numpy.random.default_rng(seed).permutation(len(groups))`` are held out. Held-out frames never
  enter a fit, an ensemble or a selection; they are the test set of every point, scored exactly
  as ``fit_margin_model`` scores its held-out trajectories (its ``_held_out_report``: AP of capture
  at k-hat 0 and 2 per frame, trajectory success from the last ``success_frames`` frames and from
  the first half, each beside the tree's AP on the same frames, and R² of both scores).
* The *pool* is every frame of the other trajectories. The points of one curve are nested: the
  frames of a smaller size are a subset of those of a larger one (selection only ever adds).
* ``strategy="random"`` adds pool frames in one seeded random order.
* ``strategy="uncertainty"`` starts from the first ``initial`` frames of that same random order.
  Then, until the next size is reached, it fits an ensemble of ``ensemble`` cheap regressors
  (gradient-boosted trees of ``ensemble_rounds`` rounds and depth 3, :func:`ensemble_member`, each
  on a bootstrap resample of the frames selected so far, on the ``frame-statistics`` features
  whatever ``kind`` is),
  predicts both scores of every unselected pool frame, and adds the frames of largest
  disagreement (:func:`disagreement`: the standard deviation over the members of the predicted
  capture score plus that of the predicted success score, predictions clipped to [0, 1]). At most
  ``batch`` frames are added per ensemble fit (default: all frames up to the next size at once). A
  fraction ``random_fraction`` (default 0.25) of every batch is drawn at random from the
  remaining pool instead, so that a batch is not only near-duplicates of one uncertain region
  (neighbouring frames of the same trajectories) and the pool keeps being covered; see
  :func:`select_uncertain`. On ``runs/l25/push10`` (boosting, sizes 100 to 800, 8 seeds) pure
  uncertainty lost about 0.006 of capture AP to random selection at every size up to 400 while
  raising success AP and R² at 100 frames; a quarter of random frames halved that loss and kept
  most of the gain, and refitting the ensemble every 50 frames instead of once per size changed
  nothing beyond the seeds' spread, so the defaults are ``random_fraction=0.25``, ``batch=None``.
* The reported model of each size is a fit of ``kind`` (with ``options``) on the selected frames
  in pool order, with regressor seed ``seed``, as ``fit_margin_model`` fits its model; the
  optional *reference* point is that fit on the whole pool, i.e. the model ``fit_margin_model``
  fits with the same arguments.

Seeds: ``seed`` itself gives the held-out split and the reported fits' regressor seed (as in
``fit_margin_model``). ``children = numpy.random.SeedSequence(seed).spawn(2)``: ``children[0]``
seeds the random order of the pool (shared by both strategies, so the uncertainty curve starts
from the random curve's first ``initial`` frames); ``children[1]`` spawns one child per ensemble
fit, in order, whose ``default_rng`` draws the bootstrap resamples and the random part of the
batch and whose ``generate_state(ensemble)`` gives the members' seeds.

This module checks the arguments and runs the protocol; the results are in
:mod:`~energy_margin.learning.curve_results`, the pool in :mod:`~energy_margin.learning.curve_pool`
and the active selection in :mod:`~energy_margin.learning.curve_selection`.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, fields
from typing import Any

import numpy as np

from energy_margin._version import __version__
from energy_margin.data.dataset import Dataset
from energy_margin.errors import (
    InvalidParameterError,
    check_choice,
    check_float,
    check_int,
    check_positive_int,
    check_seed,
)
from energy_margin.learning.curve_pool import (
    _Pool,
    _pool,
    _rows,
    held_out_trajectories,
)
from energy_margin.learning.curve_results import (
    CurvePoint,
    LearningCurve,
    QuestionAp,
)
from energy_margin.learning.curve_selection import (
    disagreement,
    ensemble_member,
    select_uncertain,
)
from energy_margin.learning.margin_file import FEATURES_OF_KIND, MarginModel
from energy_margin.learning.margin_frames import check_same_task
from energy_margin.learning.margin_report import _held_out_report
from energy_margin.learning.regressors import KINDS, fit_regressor

__all__ = [
    "QUESTIONS",
    "STRATEGIES",
    "CurvePoint",
    "LearningCurve",
    "QuestionAp",
    "disagreement",
    "frames_needed",
    "held_out_trajectories",
    "learning_curve",
    "select_uncertain",
]

#: How the frames to analyse are chosen.
STRATEGIES = ("random", "uncertainty")
#: The held-out AP questions of ``fit_margin_model``'s report, in the order they are printed.
QUESTIONS = ("capture", "capture_window2", "success", "success_first_half")


def _check_sizes(sizes: Sequence[int], pool_frames: int) -> tuple[int, ...]:
    try:
        values = list(sizes)
    except TypeError:
        raise InvalidParameterError("sizes", f"must be a sequence of frame counts, got {sizes!r}") from None
    if not values:
        raise InvalidParameterError("sizes", "must hold at least one frame count")
    checked = []
    for value in values:
        try:
            checked.append(check_int("sizes", value, minimum=1))
        except InvalidParameterError:
            raise InvalidParameterError("sizes", f"must hold positive integers, got {value!r}") from None
    if any(b <= a for a, b in itertools.pairwise(checked)):
        raise InvalidParameterError("sizes", f"must be strictly increasing, got {checked}")
    if checked[-1] > pool_frames:
        raise InvalidParameterError(
            "sizes", f"asks for {checked[-1]} frames but the training pool holds {pool_frames} (the rest are held out)"
        )
    return tuple(checked)


def learning_curve(
    datasets: Sequence[Dataset],
    *,
    kind: str,
    sizes: Sequence[int],
    strategy: str,
    seed: int,
    holdout: float = 0.25,
    success_frames: int = 3,
    initial: int | None = None,
    ensemble: int = 4,
    ensemble_rounds: int = 40,
    random_fraction: float = 0.25,
    batch: int | None = None,
    reference: bool = False,
    **options: Any,
) -> LearningCurve:
    """Held-out AP of a learned margin fitted on growing numbers of analysed frames.

    The protocol (pool, held-out trajectories, both strategies, seeds) is the module docstring's.

    Args:
        datasets: analysed datasets of one task (as for ``fit_margin_model``).
        kind: regressor kind of the reported fits (:data:`~energy_margin.learning.regressors.KINDS`).
        sizes: frames of each point, strictly increasing, the last at most the pool's frames.
        strategy: ``"random"`` or ``"uncertainty"`` (:data:`STRATEGIES`).
        seed: seed of the split, the reported fits, the pool order and the ensembles.
        holdout: fraction of the trajectories held out, in (0, 1).
        success_frames: k-bar of the trajectory success AP, >= 1.
        initial: uncertainty: random frames it starts from, in [1, sizes[0]] (default
            ``max(1, sizes[0] // 2)``); ignored by ``random``.
        ensemble: uncertainty: members of the selection ensemble, >= 2.
        ensemble_rounds: uncertainty: boosting rounds of each member, >= 1.
        random_fraction: uncertainty: fraction of each batch drawn at random, in [0, 1] (0.25).
        batch: uncertainty: most frames added per ensemble fit, >= 1 (default: up to the next size).
        reference: also fit on the whole pool (:attr:`LearningCurve.reference`).
        options: regressor options of the reported fits (``fit_regressor``).

    Raises:
        EnergyMarginError: datasets of different tasks, without scores, or too few trajectories.
        ValueError: a bad argument (an ``InvalidParameterError`` naming it), or a bad regressor option.
    """
    check_choice("kind", kind, KINDS)
    check_choice("strategy", strategy, STRATEGIES)
    seed = check_seed(seed)
    holdout = check_float("holdout", holdout, minimum=0.0, maximum=1.0, exclusive_minimum=True, exclusive_maximum=True)
    success_frames = check_positive_int("success_frames", success_frames)
    check_same_task(datasets)
    held = held_out_trajectories(datasets, seed=seed, holdout=holdout)
    checked_sizes = _check_sizes(sizes, _pool_frames(datasets, held))
    selection = None
    if strategy == "uncertainty":
        selection = _check_selection(checked_sizes[0], initial, ensemble, ensemble_rounds, random_fraction, batch)
    pool = _pool(datasets, set(held), kind)
    point = _point_fitter(pool, kind=kind, seed=seed, success_frames=success_frames, options=options)
    points = _fit_points(pool, checked_sizes, selection, point, seed)
    full = point(np.arange(len(pool.ids)), 0.0) if reference else None
    return LearningCurve(
        kind=kind,
        strategy=strategy,
        seed=seed,
        holdout=holdout,
        success_frames=success_frames,
        sizes=checked_sizes,
        **_selection_fields(selection),
        options=dict(options),
        pool_frames=len(pool.ids),
        pool_trajectories=int(pool.groups.max()) + 1,
        held_out=tuple(held),
        held_out_frames=len(pool.test_y),
        points=tuple(points),
        reference=full,
    )


def _pool_frames(datasets: Sequence[Dataset], held: Sequence[tuple[int, int]]) -> int:
    """Frames of the training pool: every trajectory's frames but the held-out ones'."""
    return sum(dataset.n_frames for d, dataset in enumerate(datasets) for t in range(dataset.n_trajectories)) - sum(
        datasets[d].n_frames for d, _ in held
    )


@dataclass(frozen=True)
class _Selection:
    """The uncertainty strategy's settings, checked (:func:`learning_curve`'s arguments of the same names)."""

    initial: int
    ensemble: int
    ensemble_rounds: int
    random_fraction: float
    batch: int | None


def _check_selection(
    first_size: int, initial: int | None, ensemble: int, ensemble_rounds: int, random_fraction: float, batch: int | None
) -> _Selection:
    """The uncertainty strategy's settings, checked (``initial`` at most the first size, ``first_size``)."""
    initial = max(1, first_size // 2) if initial is None else initial
    return _Selection(
        initial=check_int("initial", initial, minimum=1, maximum=first_size),
        ensemble=check_int("ensemble", ensemble, minimum=2),
        ensemble_rounds=check_positive_int("ensemble_rounds", ensemble_rounds),
        random_fraction=check_float("random_fraction", random_fraction, minimum=0.0, maximum=1.0),
        batch=check_positive_int("batch", batch) if batch is not None else None,
    )


def _selection_fields(selection: _Selection | None) -> dict[str, Any]:
    """The uncertainty strategy's fields of a :class:`LearningCurve` (each ``None`` for ``random``)."""
    if selection is None:
        return dict.fromkeys(field.name for field in fields(_Selection))
    return asdict(selection)


def _fit_points(
    pool: _Pool,
    sizes: tuple[int, ...],
    selection: _Selection | None,
    point: Callable[[np.ndarray, float], CurvePoint],
    seed: int,
) -> list[CurvePoint]:
    """The curve's points: ``random`` without a ``selection``, else ``uncertainty``; ``point`` fits one."""
    order_seed, ensemble_seeds = np.random.SeedSequence(seed).spawn(2)
    order = np.random.default_rng(order_seed).permutation(len(pool.ids))
    if selection is None:
        return [point(order[:size], 0.0) for size in sizes]
    return _uncertainty_points(pool, order, sizes, point, **asdict(selection), seeds=ensemble_seeds)


def _point_fitter(
    pool: _Pool, *, kind: str, seed: int, success_frames: int, options: dict[str, Any]
) -> Callable[[np.ndarray, float], CurvePoint]:
    """``point(rows, selection_seconds)``: the reported fit on pool ``rows`` and its held-out report."""
    task = pool.frames[0].dataset.task
    definition = FEATURES_OF_KIND[kind](task)
    n_objects = [item.dataset.n_objects for item in pool.frames]

    def point(rows: np.ndarray, selection_seconds: float) -> CurvePoint:
        rows = np.sort(rows)
        fit_options = {"groups": pool.groups[rows], **options} if kind == "set" else dict(options)
        started = time.perf_counter()
        regressor = fit_regressor(kind, _rows(pool.features, rows), pool.targets[rows], seed=seed, **fit_options)
        fit_seconds = time.perf_counter() - started
        model = MarginModel(
            task_name=task.name,
            task_config=task.config.to_dict(),
            feature_set=definition.identifier,
            package_version=__version__,
            kind=kind,
            feature_names=definition.names,
            regressor=regressor,
            n_objects_range=(min(n_objects), max(n_objects)),
        )
        report = _held_out_report(
            model, pool.frames, pool.held, pool.test_x, pool.test_y, success_frames=success_frames
        )
        return CurvePoint(
            frames=len(rows),
            trajectories=len(np.unique(pool.groups[rows])),
            ap={q: QuestionAp(report["ap"][q]["learned"], report["ap"][q]["tree"]) for q in QUESTIONS},
            r2_capture=report["r2"]["capture"],
            r2_success=report["r2"]["success"],
            fit_seconds=fit_seconds,
            selection_seconds=selection_seconds,
            selected=tuple(pool.ids[i] for i in rows),
        )

    return point


def _uncertainty_points(
    pool: _Pool,
    order: np.ndarray,
    sizes: tuple[int, ...],
    point: Callable[[np.ndarray, float], CurvePoint],
    *,
    initial: int,
    ensemble: int,
    ensemble_rounds: int,
    random_fraction: float,
    batch: int | None,
    seeds: np.random.SeedSequence,
) -> list[CurvePoint]:
    """The points of the uncertainty strategy: from ``initial`` random frames, batches of largest disagreement."""
    points = []
    selection_seconds = 0.0
    chosen = list(order[:initial])
    is_chosen = np.zeros(len(pool.ids), dtype=bool)
    is_chosen[chosen] = True
    member = ensemble_member(ensemble_rounds)
    for size in sizes:
        while len(chosen) < size:
            count = size - len(chosen) if batch is None else min(batch, size - len(chosen))
            started = time.perf_counter()
            picked = select_uncertain(
                pool.flat,
                pool.targets,
                np.asarray(chosen),
                order[~is_chosen[order]],
                count,
                members=ensemble,
                seed=seeds.spawn(1)[0],
                random_fraction=random_fraction,
                fit_member=member,
            )
            selection_seconds += time.perf_counter() - started
            chosen.extend(int(i) for i in picked)
            is_chosen[picked] = True
        points.append(point(np.asarray(chosen), selection_seconds))
    return points


def frames_needed(curve: LearningCurve, reference: CurvePoint, *, tolerance: float = 0.02) -> int | None:
    """The fewest frames from which every later point is within ``tolerance`` of ``reference``.

    A point is within when its learned AP is at least the reference's learned AP minus
    ``tolerance`` on every question of :data:`QUESTIONS` (a point above the reference counts; a
    question whose held-out labels hold one class, AP ``None``, is skipped).
    The answer is the size of the first point from which that holds at every larger size of the
    curve, or ``None`` when the last point is not within ("not reached").
    """
    tolerance = check_float("tolerance", tolerance, minimum=0.0)
    needed: int | None = None
    for item in curve.points:
        within = all(_within(item.ap[q].learned, reference.ap[q].learned, tolerance) for q in QUESTIONS)
        if not within:
            needed = None
        elif needed is None:
            needed = item.frames
    return needed


def _within(learned: float | None, target: float | None, tolerance: float) -> bool:
    if target is None:
        return True
    return learned is not None and learned >= target - tolerance
