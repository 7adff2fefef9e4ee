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
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from energy_margin._version import __version__
from energy_margin.data.dataset import Dataset
from energy_margin.errors import (
    EnergyMarginError,
    InvalidParameterError,
    check_choice,
    check_float,
    check_int,
    check_positive_int,
    check_seed,
)
from energy_margin.learning.features import SetInputs
from energy_margin.learning.margin_model import (
    FEATURES_OF_KIND,
    MarginModel,
    _concatenate,
    _Frames,
    _held_out_report,
    check_same_task,
    training_frames,
)
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

#: One frame: (dataset index, trajectory, frame index).
FrameId = tuple[int, int, int]
#: Fits one ensemble member: ``fit_member(features (F, D), targets (F, 2), seed)`` -> a regressor.
MemberFit = Callable[[np.ndarray, np.ndarray, int], Any]


@dataclass(frozen=True)
class QuestionAp:
    """Held-out Average Precision of one question: the learned margin's beside the tree's.

    Both are ``None`` when the held-out labels of the question hold a single class.
    """

    learned: float | None
    tree: float | None


@dataclass(frozen=True)
class CurvePoint:
    """One point of a learning curve: a fit of the margin on ``frames`` selected pool frames.

    Attributes:
        frames: frames used, i.e. trees grown.
        trajectories: distinct trajectories those frames come from.
        ap: held-out AP of each question of :data:`QUESTIONS`.
        r2_capture: held-out R² of the capture score (``None`` when the truth is constant).
        r2_success: held-out R² of the success score (``None`` likewise).
        fit_seconds: wall time of the reported fit.
        selection_seconds: wall time of the ensemble fits and predictions so far (0 for random).
        selected: the frames used, sorted.
    """

    frames: int
    trajectories: int
    ap: dict[str, QuestionAp]
    r2_capture: float | None
    r2_success: float | None
    fit_seconds: float
    selection_seconds: float
    selected: tuple[FrameId, ...] = field(repr=False)

    def to_dict(self, *, selected: bool = False) -> dict[str, Any]:
        """JSON-compatible form (the selected frames only when asked: they are many)."""
        out: dict[str, Any] = {
            "frames": self.frames,
            "trajectories": self.trajectories,
            "ap": {question: {"learned": v.learned, "tree": v.tree} for question, v in self.ap.items()},
            "r2": {"capture": self.r2_capture, "success": self.r2_success},
            "fit_seconds": self.fit_seconds,
            "selection_seconds": self.selection_seconds,
        }
        if selected:
            out["selected"] = [list(frame) for frame in self.selected]
        return out


@dataclass(frozen=True)
class LearningCurve:
    """A learning curve: one :class:`CurvePoint` per size, on fixed held-out trajectories.

    Attributes:
        kind: regressor kind of the reported fits.
        strategy: ``"random"`` or ``"uncertainty"``.
        seed: the seed given.
        holdout: fraction of the trajectories held out.
        success_frames: k-bar of the trajectory success AP.
        sizes: the sizes asked for.
        initial: random frames the uncertainty selection starts from (``None`` for random).
        ensemble: members of the selection ensemble (``None`` for random).
        ensemble_rounds: boosting rounds of each member (``None`` for random).
        random_fraction: fraction of each selected batch drawn at random (``None`` for random).
        batch: most frames added per ensemble fit (``None``: up to the next size).
        options: the reported fits' regressor options.
        pool_frames: frames of the training pool.
        pool_trajectories: trajectories of the training pool.
        held_out: the held-out ``(dataset, trajectory)`` pairs, sorted.
        held_out_frames: frames of the held-out trajectories.
        points: one per size, in order.
        reference: the fit on the whole pool, when asked for.
    """

    kind: str
    strategy: str
    seed: int
    holdout: float
    success_frames: int
    sizes: tuple[int, ...]
    initial: int | None
    ensemble: int | None
    ensemble_rounds: int | None
    random_fraction: float | None
    batch: int | None
    options: dict[str, Any]
    pool_frames: int
    pool_trajectories: int
    held_out: tuple[tuple[int, int], ...]
    held_out_frames: int
    points: tuple[CurvePoint, ...]
    reference: CurvePoint | None

    def to_dict(self, *, selected: bool = False) -> dict[str, Any]:
        """JSON-compatible form."""
        return {
            "kind": self.kind,
            "strategy": self.strategy,
            "seed": self.seed,
            "holdout": self.holdout,
            "success_frames": self.success_frames,
            "sizes": list(self.sizes),
            "initial": self.initial,
            "ensemble": self.ensemble,
            "ensemble_rounds": self.ensemble_rounds,
            "random_fraction": self.random_fraction,
            "batch": self.batch,
            "options": {key: _plain(value) for key, value in self.options.items()},
            "pool_frames": self.pool_frames,
            "pool_trajectories": self.pool_trajectories,
            "held_out": [list(pair) for pair in self.held_out],
            "held_out_frames": self.held_out_frames,
            "points": [point.to_dict(selected=selected) for point in self.points],
            "reference": None if self.reference is None else self.reference.to_dict(selected=False),
            "package_version": __version__,
        }


def held_out_trajectories(datasets: Sequence[Dataset], *, seed: int, holdout: float) -> list[tuple[int, int]]:
    """The ``(dataset, trajectory)`` pairs ``fit_margin_model`` holds out with ``seed`` and ``holdout``, sorted.

    Raises:
        EnergyMarginError: fewer than 2 trajectories in all.
    """
    groups = [(d, t) for d, dataset in enumerate(datasets) for t in range(dataset.n_trajectories)]
    if len(groups) < 2:
        raise EnergyMarginError("a margin model needs at least 2 trajectories (one is held out)")
    order = np.random.default_rng(seed).permutation(len(groups))
    n_held = min(len(groups) - 1, max(1, round(holdout * len(groups))))
    return sorted(groups[i] for i in order[:n_held])


def disagreement(predictions: np.ndarray) -> np.ndarray:
    """Disagreement of an ensemble on each frame: std over members of capture plus that of success.

    Args:
        predictions: shape (M, F, 2), the M members' capture and success scores of F frames.

    Returns:
        Shape (F,).
    """
    predictions = np.asarray(predictions, dtype=float)
    if predictions.ndim != 3 or predictions.shape[2] != 2:
        raise InvalidParameterError("predictions", f"must have shape (members, frames, 2), got {predictions.shape}")
    return predictions.std(axis=0).sum(axis=1)


def select_uncertain(
    features: np.ndarray,
    targets: np.ndarray,
    selected: np.ndarray,
    candidates: np.ndarray,
    count: int,
    *,
    members: int,
    seed: np.random.SeedSequence | int,
    random_fraction: float = 0.0,
    fit_member: MemberFit | None = None,
) -> np.ndarray:
    """Pick ``count`` of ``candidates`` by the disagreement of an ensemble fitted on ``selected``.

    Each of the ``members`` members is fitted by ``fit_member`` on a bootstrap resample of the
    ``selected`` rows (their ``targets`` are the revealed scores); the members predict every
    candidate, and the ``count - round(random_fraction * count)`` candidates of largest
    :func:`disagreement` are taken (ties: the earlier candidate first), then the rest of
    ``count`` drawn uniformly from the other candidates.

    Args:
        features: features of every pool frame, shape (P, D).
        targets: capture and success scores, shape (P, 2); only the ``selected`` rows are read.
        selected: pool rows already selected, shape (S,), S >= 1.
        candidates: pool rows that may be picked, shape (C,), in tie-breaking order.
        count: frames to pick, 1 <= count <= C.
        members: ensemble size, >= 2.
        seed: seeds the bootstrap resamples, the members and the random part.
        random_fraction: fraction of ``count`` drawn at random, in [0, 1].
        fit_member: fits one member (default: :func:`ensemble_member` of 40 rounds).

    Returns:
        The picked pool rows, shape (count,): the uncertain ones by decreasing disagreement, then
        the random ones.
    """
    selected = np.asarray(selected, dtype=np.int64)
    candidates = np.asarray(candidates, dtype=np.int64)
    check_int("count", count, minimum=1, maximum=len(candidates))
    check_int("members", members, minimum=2)
    check_float("random_fraction", random_fraction, minimum=0.0, maximum=1.0)
    if len(selected) == 0:
        raise InvalidParameterError("selected", "must hold at least one row")
    fit = fit_member if fit_member is not None else ensemble_member(40)
    sequence = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
    rng = np.random.default_rng(sequence)
    member_seeds = sequence.generate_state(members, np.uint32)
    candidate_x = features[candidates]
    predictions = np.empty((members, len(candidates), 2))
    for m in range(members):
        rows = selected[rng.integers(0, len(selected), size=len(selected))]
        model = fit(features[rows], targets[rows], int(member_seeds[m]))
        predictions[m] = np.clip(model.predict(candidate_x), 0.0, 1.0)
    n_random = min(count, round(random_fraction * count))
    ranked = np.argsort(-disagreement(predictions), kind="stable")
    uncertain = ranked[: count - n_random]
    rest = np.setdiff1d(np.arange(len(candidates)), uncertain)
    randomly = rng.choice(rest, size=n_random, replace=False) if n_random else np.empty(0, dtype=np.int64)
    return candidates[np.concatenate([uncertain, randomly]).astype(np.int64)]


def ensemble_member(rounds: int) -> MemberFit:
    """A cheap ensemble member: per score, boosted trees of ``rounds`` rounds and depth 3.

    scikit-learn's ``HistGradientBoostingRegressor`` (learning rate 0.2, no early stopping) with
    leaves of at least ``max(1, min(20, F // 10))`` of the F frames it is fitted on (scikit-learn's
    default of 20 would leave a member fitted on a few dozen frames without a split), on one
    thread as :func:`~energy_margin.learning.regressors.fit_regressor` fits.
    """

    def fit(features: np.ndarray, targets: np.ndarray, seed: int) -> _Member:
        from sklearn.ensemble import HistGradientBoostingRegressor
        from threadpoolctl import threadpool_limits

        leaf = max(1, min(20, len(features) // 10))
        with threadpool_limits(limits=1):
            models = [
                HistGradientBoostingRegressor(
                    max_iter=rounds,
                    learning_rate=0.2,
                    max_depth=3,
                    min_samples_leaf=leaf,
                    early_stopping=False,
                    random_state=seed,
                ).fit(features, targets[:, output])
                for output in range(2)
            ]
        return _Member(models)

    return fit


class _Member:
    """Predictions of one fitted model per score, shape (F, 2)."""

    def __init__(self, models: list[Any]) -> None:
        self.models = models

    def predict(self, features: np.ndarray) -> np.ndarray:
        from threadpoolctl import threadpool_limits

        with threadpool_limits(limits=1):
            return np.stack([model.predict(features) for model in self.models], axis=1)


@dataclass(frozen=True)
class _Pool:
    """The training pool and the held-out test set of one split."""

    frames: list[_Frames]
    held: set[tuple[int, int]]
    ids: list[FrameId]  # pool row -> frame, in (dataset, trajectory, frame) order
    features: Any  # (P, D) array or SetInputs of the pool frames, in pool order
    flat: np.ndarray  # (P, D) frame-statistics features of the pool frames
    targets: np.ndarray  # (P, 2)
    groups: np.ndarray  # (P,) pool trajectory of every row
    test_x: Any
    test_y: np.ndarray


def _pool(datasets: Sequence[Dataset], held: set[tuple[int, int]], kind: str) -> _Pool:
    frames = training_frames(datasets, kind=kind)
    ids: list[FrameId] = []
    parts: list[Any] = []
    targets: list[np.ndarray] = []
    groups: list[np.ndarray] = []
    test_parts: list[Any] = []
    test_targets: list[np.ndarray] = []
    trajectory = 0
    for d, item in enumerate(frames):
        k = item.dataset.n_frames
        for t in range(item.dataset.n_trajectories):
            block = _rows(item.features, np.arange(t * k, (t + 1) * k))
            scores = np.stack([item.capture[t], item.success[t]], axis=1)
            if (d, t) in held:
                test_parts.append(block)
                test_targets.append(scores)
                continue
            ids.extend((d, t, i) for i in range(k))
            parts.append(block)
            targets.append(scores)
            groups.append(np.full(k, trajectory))
            trajectory += 1
    features = _concatenate(parts)
    return _Pool(
        frames=frames,
        held=held,
        ids=ids,
        features=features,
        flat=features.frame if isinstance(features, SetInputs) else features,
        targets=np.concatenate(targets),
        groups=np.concatenate(groups),
        test_x=_concatenate(test_parts),
        test_y=np.concatenate(test_targets),
    )


def _rows(features: Any, rows: np.ndarray) -> Any:
    """The rows ``rows`` of features (F, D) or of set inputs."""
    return features.take(rows) if isinstance(features, SetInputs) else features[rows]


def _plain(value: Any) -> Any:
    """A JSON-compatible copy of an option value (tuples and arrays as lists)."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, tuple | list):
        return [_plain(item) for item in value]
    return value


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
    held_set = set(held)
    pool_frames = sum(
        dataset.n_frames for d, dataset in enumerate(datasets) for t in range(dataset.n_trajectories)
    ) - sum(datasets[d].n_frames for d, _ in held)
    checked_sizes = _check_sizes(sizes, pool_frames)
    active = strategy == "uncertainty"
    if active:
        initial = max(1, checked_sizes[0] // 2) if initial is None else initial
        initial = check_int("initial", initial, minimum=1, maximum=checked_sizes[0])
        ensemble = check_int("ensemble", ensemble, minimum=2)
        ensemble_rounds = check_positive_int("ensemble_rounds", ensemble_rounds)
        random_fraction = check_float("random_fraction", random_fraction, minimum=0.0, maximum=1.0)
        if batch is not None:
            batch = check_positive_int("batch", batch)

    pool = _pool(datasets, held_set, kind)
    order_seed, ensemble_seeds = np.random.SeedSequence(seed).spawn(2)
    order = np.random.default_rng(order_seed).permutation(len(pool.ids))
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

    points = []
    selection_seconds = 0.0
    if not active:
        for size in checked_sizes:
            points.append(point(order[:size], 0.0))
    else:
        assert initial is not None
        chosen = list(order[:initial])
        is_chosen = np.zeros(len(pool.ids), dtype=bool)
        is_chosen[chosen] = True
        member = ensemble_member(ensemble_rounds)
        for size in checked_sizes:
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
                    seed=ensemble_seeds.spawn(1)[0],
                    random_fraction=random_fraction,
                    fit_member=member,
                )
                selection_seconds += time.perf_counter() - started
                chosen.extend(int(i) for i in picked)
                is_chosen[picked] = True
            points.append(point(np.asarray(chosen), selection_seconds))
    full = point(np.arange(len(pool.ids)), 0.0) if reference else None
    return LearningCurve(
        kind=kind,
        strategy=strategy,
        seed=seed,
        holdout=holdout,
        success_frames=success_frames,
        sizes=checked_sizes,
        initial=initial if active else None,
        ensemble=ensemble if active else None,
        ensemble_rounds=ensemble_rounds if active else None,
        random_fraction=random_fraction if active else None,
        batch=batch if active else None,
        options=dict(options),
        pool_frames=len(pool.ids),
        pool_trajectories=int(pool.groups.max()) + 1,
        held_out=tuple(held),
        held_out_frames=len(pool.test_y),
        points=tuple(points),
        reference=full,
    )


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
