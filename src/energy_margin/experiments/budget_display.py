"""The figure of AP against the expansion budget: :class:`BudgetDisplay`, built from summary rows.

One panel per question, one line per tree method with its 95 % interval shaded and drawn as error
bars, and each baseline (a row of a method outside the tree methods) as a horizontal dashed line.
``budget`` draws it from its three questions (``DIR/budget/budget.png``), ``study`` from its six
(``OUT/study_<task>.png``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from energy_margin.planning.methods import METHODS
from energy_margin.runs.display import Display

__all__ = [
    "BASELINE_COLORS",
    "BudgetDisplay",
]

#: Colours of the baselines' lines.
BASELINE_COLORS = {"current_state": "grey", "distance": "black", "chance": "tab:brown"}


@dataclass
class BudgetDisplay(Display):
    """AP against budget per method, one panel per question.

    Attributes:
        rows: summary rows (``method``, ``budget`` and each question with ``_low``/``_high``).
        questions: the questions, one panel each.
        labels: panel titles by question (a question without one is titled by its name).
        title: figure title.

    """

    rows: list[dict[str, Any]]
    questions: tuple[str, ...]
    labels: dict[str, str] = field(default_factory=dict)
    title: str = ""

    @classmethod
    def from_result(
        cls,
        rows: Sequence[dict[str, Any]],
        *,
        questions: Sequence[str],
        labels: dict[str, str] | None = None,
        title: str = "",
    ) -> BudgetDisplay:
        """The display of the summary ``rows`` of a budget sweep or of one task of a study."""
        return cls([dict(row) for row in rows], tuple(questions), dict(labels or {}), title)

    def draw(self, plt: Any) -> Any:
        """Draw the panels with pyplot ``plt``; the figure."""
        questions = self.questions
        # At most three panels a row: budget's three questions in one row, the study's six in two.
        columns = min(3, len(questions))
        rows_of_panels = -(-len(questions) // columns)
        figure, grid = plt.subplots(
            rows_of_panels, columns, figsize=(4.2 * columns, 3.6 * rows_of_panels), sharey=True, squeeze=False
        )
        axes = list(grid.ravel()[: len(questions)])
        for spare in grid.ravel()[len(questions) :]:
            spare.set_visible(False)
        for axis, question in zip(axes, questions, strict=True):
            self._draw_panel(axis, question)
        for row_axes in grid:
            row_axes[0].set_ylabel("AP (95 % CI over trajectories)")
        axes[-1].legend(fontsize=8, loc="lower right")
        if self.title:
            figure.suptitle(self.title)
        figure.tight_layout()
        return figure

    def _draw_panel(self, axis: Any, question: str) -> None:
        for method in dict.fromkeys(r["method"] for r in self.rows):
            mine = [r for r in self.rows if r["method"] == method and r.get(question) is not None]
            if not mine:
                continue
            if method in METHODS:
                _draw_method(axis, method, mine, question)
            else:
                color = BASELINE_COLORS.get(method, "black")
                axis.axhline(mine[0][question], linestyle="--", linewidth=1, label=method, color=color)
        axis.set_xscale("log")
        axis.set_xlabel("expansions per frame")
        axis.set_title(self.labels.get(question, question))
        axis.grid(True, alpha=0.3)


def _draw_method(axis: Any, method: str, rows: list[dict[str, Any]], question: str) -> None:
    budgets = [r["budget"] for r in rows]
    values = [r[question] for r in rows]
    line = axis.plot(budgets, values, marker="o", label=method)[0]
    low = [r[f"{question}_low"] for r in rows]
    high = [r[f"{question}_high"] for r in rows]
    if None not in low and None not in high:
        axis.fill_between(budgets, low, high, color=line.get_color(), alpha=0.15)
        below = [v - lo for v, lo in zip(values, low, strict=True)]
        above = [hi - v for v, hi in zip(values, high, strict=True)]
        axis.errorbar(budgets, values, yerr=[below, above], fmt="none", ecolor=line.get_color(), capsize=3)
