"""The study's figures, built from its result: AP against budget and AP against lambda per task.

:func:`draw_study` writes, for every task of a :class:`~energy_margin.experiments.study_result.StudyResult`,
``study_<task>.png`` (a :class:`~energy_margin.experiments.budget_display.BudgetDisplay` of the six
questions) and ``study_lambda_<task>.png`` (a :class:`LambdaDisplay`) into ``OUT`` and ``OUT/<task>``,
once the tables are written. Without matplotlib nothing is drawn.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from energy_margin.experiments.budget_display import BudgetDisplay
from energy_margin.experiments.study_result import LABELS, QUESTION_NAMES, StudyResult
from energy_margin.runs.display import Display

__all__ = [
    "LambdaDisplay",
    "draw_study",
    "plot_lambda",
    "task_title",
]


@dataclass
class LambdaDisplay(Display):
    """AP of every question against lambda (log axis, intervals shaded, the task's lambda dashed).

    Attributes:
        rows: lambda rows of one task with lambda > 0 (``lambda`` and each question with
            ``_low``/``_high``).
        default: the task's lambda, 1/J.
        title: figure title.

    """

    rows: list[dict[str, Any]]
    default: float
    title: str = ""

    @classmethod
    def from_result(cls, rows: Sequence[dict[str, Any]], default: float, title: str = "") -> LambdaDisplay:
        """The display of a task's lambda rows (a lambda of 0 has no place on the log axis)."""
        return cls([dict(r) for r in rows if r["lambda"] > 0], float(default), title)

    def draw(self, plt: Any) -> Any:
        """Draw the curves with pyplot ``plt``; the figure."""
        figure, axis = plt.subplots(figsize=(6.4, 4.2))
        values = [r["lambda"] for r in self.rows]
        for question in QUESTION_NAMES:
            points = [(v, r) for v, r in zip(values, self.rows, strict=True) if r.get(question) is not None]
            if not points:
                continue
            xs = [v for v, _ in points]
            line = axis.plot(xs, [r[question] for _, r in points], marker="o", label=LABELS[question])
            low = [r[f"{question}_low"] for _, r in points]
            high = [r[f"{question}_high"] for _, r in points]
            if None not in low and None not in high:
                axis.fill_between(xs, low, high, color=line[0].get_color(), alpha=0.12)
        axis.axvline(self.default, linestyle="--", color="black", linewidth=1, label=f"task lambda = {self.default:g}")
        axis.set_xscale("log")
        axis.set_xlabel("lambda [1/J]")
        axis.set_ylabel("AP (95 % CI over trajectories)")
        axis.grid(True, alpha=0.3)
        axis.legend(fontsize=7, loc="lower left")
        if self.title:
            axis.set_title(self.title, fontsize=10)
        figure.tight_layout()
        return figure


def plot_lambda(rows: list[dict[str, Any]], path: Path, default: float, title: str = "") -> Path | None:
    """Write the :class:`LambdaDisplay` of a task's lambda ``rows`` to ``path``.

    Args:
        rows: lambda rows of one task (``lambda`` and each question with ``_low``/``_high``).
        path: the PNG to write.
        default: the task's lambda, 1/J.
        title: figure title.

    Returns:
        ``path``, or ``None`` without matplotlib or without rows.

    """
    display = LambdaDisplay.from_result(rows, default, title)
    return display.save(path) if display.rows else None


def task_title(result: StudyResult, task: str) -> str:
    """The figures' title of ``task``: objects per scene and the dataset's size."""
    objects = result.meta["tasks"][task]["objects"]
    return f"{task}, n_o = {objects}, {result.meta['trajectories']} x {result.meta['frames']} frames"


def draw_study(result: StudyResult, out: Path) -> list[Path]:
    """Write every task's two figures into ``out`` and ``out/<task>``; the files written."""
    written: list[Path] = []
    for task in result.meta.get("tasks", {}):
        title = task_title(result, task)
        rows = [r for r in result.rows if r["task"] == task]
        lambdas = [r for r in result.lambdas if r["task"] == task]
        lam = float(result.meta["tasks"][task]["likelihood_lambda"])
        budget = BudgetDisplay.from_result(rows, questions=QUESTION_NAMES, labels=LABELS, title=title)
        for folder in (out, out / task):
            paths = (
                budget.save(folder / f"study_{task}.png"),
                plot_lambda(lambdas, folder / f"study_lambda_{task}.png", lam, title),
            )
            written += [path for path in paths if path is not None]
    return written
