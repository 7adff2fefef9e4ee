"""Live scoring: the energy margins of one state of a running robot within a latency budget.

:func:`score_state` grows the frame's tree (:func:`~energy_margin.analysis.frame.analyze_frame`,
the same EST as ``analyze``) until a wall-clock deadline passes or ``max_expansions`` expansions are
done, and scores what it reached. The deadline is checked after every expansion (after every round
with ``batch`` > 1), so a call overruns its budget by at most one expansion plus the final scoring
(a millisecond or so for the built-in tasks).

Determinism: with a wall-clock budget the number of expansions reached depends on the machine and
its load, so two calls with the same seed may stop at different expansions and return different
scores; the expansions that are done are the same (the controls are a fixed function of the seed
and the expansion number), so a call that reaches more expansions extends the other's tree. For a
reproducible score pass ``budget_s=None`` with ``max_expansions``: growth then stops at exactly that
many expansions and the scores depend only on the state, the seed and the settings.

The learned path, a fitted regressor's estimate in microseconds, is
:meth:`energy_margin.learning.margin_model.MarginModel.score_state`; it returns the same
:class:`LiveScore`.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from energy_margin.analysis.continuation import Controller, controlled_success
from energy_margin.analysis.frame import AnalyzerConfig, analyze_frame
from energy_margin.errors import InvalidParameterError, check_positive_float, check_positive_int
from energy_margin.planning import CostField
from energy_margin.sim import Simulator
from energy_margin.tasks import Task
from energy_margin.world.state import FrameState

__all__ = [
    "MAX_EXPANSIONS",
    "FeedbackContinuation",
    "LiveScore",
    "score_state",
]

#: Default cap on the expansions of one live call (the tree's arrays are sized for it: a larger cap
#: costs set-up time; raise it for budgets beyond a few tenths of a second).
MAX_EXPANSIONS = 2_000


@dataclass(frozen=True)
class LiveScore:
    """The estimate of one live call.

    Attributes:
        capture: capture score, in [0, 1].
        success: success score, in [0, 1].
        expansions: tree expansions reached (accepted or rejected); 0 for the learned path.
        nodes: tree nodes including the root; 0 for the learned path.
        seconds: wall time of the call, s (building a simulator included when none was given).
        stopped_by: ``"budget"`` (the deadline passed), ``"max_expansions"`` (the cap was
            reached first) or ``"learned"`` (a regressor's estimate, no tree).
        rejected: reached states the tree rejected for leaving the state box (-1: no tree).
        diverged: reached states the tree rejected for a non-finite number (-1: no tree).
        tree_capture: the tree's own capture score before the capture gate, what a capture alarm
            watches (NaN: no tree).
        continuation_s: wall time of the feedback continuation, s (0: none ran).

    """

    capture: float
    success: float
    expansions: int
    nodes: int
    seconds: float
    stopped_by: str
    rejected: int = -1
    diverged: int = -1
    tree_capture: float = math.nan
    continuation_s: float = 0.0


@dataclass(frozen=True)
class FeedbackContinuation:
    """The success score continued under the robot's own feedback controller (a policy) from the tree.

    Attributes:
        controllers: makes the controller of one continuation (called once per draw; see
            :func:`~energy_margin.analysis.continuation.controlled_success`).
        horizon_s: when the continuations end, s after the state (the rest of the episode).
        period_s: time between two commands of the controller, s.
        samples: nodes drawn by likelihood weight, >= 1.

    """

    controllers: Callable[[], Controller]
    horizon_s: float
    period_s: float
    samples: int = 4


def _feedback_success(
    simulator: Simulator,
    task: Task,
    state: FrameState,
    field: CostField,
    settings: AnalyzerConfig,
    feedback: FeedbackContinuation,
    seed: int,
) -> float:
    """The success score continued under the robot's feedback controller from the tree ``field``'s likely states."""
    lam = settings.likelihood_lambda if settings.likelihood_lambda is not None else task.config.likelihood_lambda
    found = controlled_success(simulator, task, state, field, feedback.controllers, lam=lam, samples=feedback.samples,
                               seed=seed, horizon=feedback.horizon_s, period=feedback.period_s)  # fmt: skip
    return found.success_score


def score_state(
    task: Task,
    state: FrameState,
    *,
    friction: float,
    drive: np.ndarray,
    budget_s: float | None = 0.05,
    seed: int = 0,
    engine: str = "mujoco",
    max_expansions: int = MAX_EXPANSIONS,
    start_time: float = 0.0,
    simulator: Simulator | None = None,
    config: AnalyzerConfig | None = None,
    feedback: FeedbackContinuation | None = None,
) -> LiveScore:
    """Score one state by growing its tree until ``budget_s`` seconds have passed.

    Args:
        task: the task.
        state: the robot's current state.
        friction: Coulomb coefficient of the scene (the running robot's estimate).
        drive: the roll-out's drive parameters, shape (n_drive,) (the task's units).
        budget_s: wall-clock budget of the whole call, s, > 0; ``None`` for no deadline (then
            ``max_expansions`` alone stops growth, and the result is deterministic).
        seed: seed of the tree's random perturbations.
        engine: physics engine (when no ``simulator`` is given).
        max_expansions: upper bound on the expansions, >= 1.
        start_time: time of the state on the end-effector's script clock, s.
        simulator: a simulator of the state's scene to reuse across calls (saves building one,
            several milliseconds); built from the task when ``None``.
        config: further analysis settings (cost model, method, projection, lambda, batch); its
            iteration and node budgets and its engine are replaced by ``max_expansions`` and
            ``engine``.
        feedback: continue the success score under the robot's feedback controller from the tree's
            likely states (after the tree, outside ``budget_s``; needs ``simulator`` and ``batch`` 1).

    Returns:
        The scores with the expansions reached and the seconds used.

    Raises:
        InvalidParameterError: a ``budget_s`` that is not > 0, a ``max_expansions`` below 1, or a
            ``feedback`` without ``simulator`` or with batched expansion.

    """
    started = time.perf_counter()
    if budget_s is not None:
        check_positive_float("budget_s", budget_s)
    check_positive_int("max_expansions", max_expansions)
    base = config if config is not None else AnalyzerConfig()
    settings = dataclasses.replace(base, expansions=int(max_expansions), nodes=None, engine=engine)
    if feedback is not None and (simulator is None or settings.batch > 1):
        raise InvalidParameterError("feedback", "needs a simulator and one expansion at a time (batch 1)")
    deadline = started + budget_s if budget_s is not None else None
    scores, field = analyze_frame(
        task,
        state,
        friction=friction,
        drive=drive,
        seed=seed,
        config=settings,
        start_time=start_time,
        simulator=simulator,
        deadline=deadline,
    )
    success, continued = scores.success_score, time.perf_counter()
    if feedback is not None:
        assert simulator is not None
        success = _feedback_success(simulator, task, state, field, settings, feedback, seed)
    return LiveScore(
        capture=scores.capture_score,
        success=success,
        expansions=scores.expansions,
        nodes=scores.nodes,
        seconds=time.perf_counter() - started,
        stopped_by="budget" if deadline is not None and scores.expansions < max_expansions else "max_expansions",
        rejected=scores.rejected,
        diverged=scores.diverged,
        tree_capture=scores.tree_capture_score,
        continuation_s=time.perf_counter() - continued if feedback is not None else 0.0,
    )
