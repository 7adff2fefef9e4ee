"""When a frame's tree may stop growing: the adaptive budget's rule, and the scores it watches.

:class:`ScoresConverged` scores the cost field every few expansions (Algorithm 1, :func:`score_field`)
and says when neither score will move by more than a tolerance; :class:`EitherStop` or-s it with a
caller's own rule. :func:`frame_seeds` spawns the per-frame seeds.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from energy_margin.analysis.scores import region_score
from energy_margin.errors import check_choice
from energy_margin.planning import CostField, TreeBudget
from energy_margin.tasks import Task, TaskRegions
from energy_margin.world.state import FrameState

__all__ = [
    "CONVERGE_RULES",
    "EitherStop",
    "ScoresConverged",
    "field_membership",
    "frame_seeds",
    "score_field",
    "scores_settled",
]

#: Rules of the adaptive budget (:class:`ScoresConverged`).
CONVERGE_RULES = ("projected", "window", "projected-reached")


def frame_seeds(seed: int, count: int) -> list[int]:
    """Per-frame seeds spawned from ``seed``: one 64-bit integer per frame."""
    children = np.random.SeedSequence(seed).spawn(count)
    return [int(child.generate_state(1, np.uint64)[0]) for child in children]


def field_membership(task: TaskRegions, root: FrameState, field: CostField) -> tuple[np.ndarray, np.ndarray]:
    """Which nodes of a cost field are captured and which successful, each shape (M,), bool."""
    captured = task.capture_inside(root, field.object_pos, field.object_vel, field.object_quat, field.robot_q)
    successful = task.success_inside(root, field.object_pos, field.object_vel, field.object_quat, field.robot_q)
    return captured, successful


def score_field(task: TaskRegions, root: FrameState, field: CostField, lam: float) -> tuple[float, float]:
    """Capture and success scores of a cost field (Algorithm 1, lines 4-11): the tree's own.

    ``analyze_frame`` gates the capture score by the root's own state afterwards
    (:func:`~energy_margin.analysis.scores.gate_capture`); the adaptive budget's rule watches
    these scores as they are.
    """
    captured, successful = field_membership(task, root, field)
    return region_score(field.costs, captured, lam), region_score(field.costs, successful, lam)


class ScoresConverged:
    """Early-stopping rule of the adaptive budget (``AnalyzerConfig.converge``).

    Called by the tree every few expansions with the cost field so far; it scores the field
    (Algorithm 1) and keeps the history of both scores, so the decision depends only on the
    tree, never on timing (same seed, same stopping point). Both rules look back ``window``
    expansions and need a check at least that far back:

    * ``"projected"``: stop when ``|s(n) - s(n - w)| * remaining / w <= tolerance`` for both
      scores, ``remaining`` being the expansions the budget still allows (the accepted nodes it
      still allows when that is fewer): the change the budget's rest would bring at the current
      rate;
    * ``"window"``: stop when both scores stayed within ``tolerance`` over the last ``window``;
    * ``"projected-reached"``: the projected rule, once the success score has left 0 at a check:
      while no node has reached the success region the score says nothing yet of how likely it
      is, so a frame whose tree never reaches it spends the whole budget.
    """

    def __init__(
        self,
        task: Task,
        root: FrameState,
        lam: float,
        *,
        tolerance: float,
        window: int,
        rule: str = "projected",
        budget: TreeBudget | None = None,
    ) -> None:
        check_choice("rule", rule, CONVERGE_RULES)
        self.task, self.root, self.lam = task, root, lam
        self.tolerance, self.window, self.rule = tolerance, window, rule
        self.budget = budget if budget is not None else TreeBudget()
        self.history: list[tuple[int, float, float]] = []

    def _remaining(self, field: CostField) -> int:
        """Expansions the budget still allows after ``field`` (accepted nodes, when fewer)."""
        remaining = self.budget.expansion_limit - field.expansions
        if self.budget.nodes is not None:
            remaining = min(remaining, self.budget.nodes - (field.nodes - 1))
        return max(remaining, 0)

    def __call__(self, field: CostField) -> bool:
        """Whether growth can stop after ``field.expansions`` expansions."""
        capture, success = score_field(self.task, self.root, field, self.lam)
        self.history.append((field.expansions, capture, success))
        return scores_settled(
            self.history, remaining=self._remaining(field), tolerance=self.tolerance, window=self.window, rule=self.rule
        )


def scores_settled(
    history: Sequence[tuple[int, float, float]], *, remaining: int, tolerance: float, window: int, rule: str
) -> bool:
    """The decision of :class:`ScoresConverged` after the last entry of ``history``.

    Args:
        history: ``(expansions, capture score, success score)`` at every check so far, in order.
        remaining: expansions the budget still allows after the last check.
        tolerance: the score tolerance.
        window: expansions the rule looks back over.
        rule: ``"projected"``, ``"window"`` or ``"projected-reached"`` (see :class:`ScoresConverged`).

    """
    if rule == "projected-reached":
        if all(entry[2] == 0 for entry in history):
            return False
        rule = "projected"
    now, capture, success = history[-1]
    earlier = [entry for entry in history if entry[0] <= now - window]
    if not earlier:
        return False
    if rule == "projected":
        then, capture_then, success_then = earlier[-1]
        factor = remaining / (now - then)
        return bool(
            abs(capture - capture_then) * factor <= tolerance and abs(success - success_then) * factor <= tolerance
        )
    recent = [(c, s) for i, c, s in history if i >= now - window]
    if len(recent) < 2:
        return False
    spread = np.ptp(np.array(recent), axis=0)
    return bool(np.all(spread <= tolerance))


class EitherStop:
    """Stop when ``first`` says so (every call) or ``periodic`` does (every ``period`` expansions)."""

    def __init__(self, first: Callable[[CostField], bool], periodic: Callable[[CostField], bool], period: int) -> None:
        self.first, self.periodic, self.period = first, periodic, period
        self.next_check = period

    def __call__(self, field: CostField) -> bool:
        """Whether growth can stop after ``field.expansions`` expansions."""
        if self.first(field):
            return True
        if field.expansions < self.next_check:
            return False
        self.next_check = (field.expansions // self.period + 1) * self.period
        return self.periodic(field)
