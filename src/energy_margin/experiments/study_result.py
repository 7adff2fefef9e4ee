"""The study's questions and its result: the tables written to ``OUT`` and printed as text.

Six questions (:func:`study_questions`): capture at k-hat = 0, 2 and 4, and trajectory success
predicted from the first 3 frames, the first 5 and the last 3. :class:`StudyResult` holds the rows
of the three tables (AP with intervals, paired differences, AP against lambda) and writes them as
``study.csv``, ``study_differences.csv``, ``study_lambda.csv`` and ``study.json``
(:mod:`energy_margin.runs.tables`); :func:`format_study` prints them.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from energy_margin.data.dataset import Dataset
from energy_margin.evaluation.bootstrap import Questions, Scored, paired_difference
from energy_margin.experiments.budget import format_table
from energy_margin.runs.tables import write_csv, write_json

__all__ = [
    "BASELINES",
    "CAPTURE_WINDOWS",
    "DIFFERENCE_FIELDS",
    "FIELDS",
    "HEADERS",
    "LABELS",
    "LAMBDA_FACTORS",
    "LAMBDA_FIELDS",
    "QUESTION_NAMES",
    "SUCCESS_SPANS",
    "TABLE_FILES",
    "StudyResult",
    "format_study",
    "method_differences",
    "positive_rates",
    "study_questions",
]

#: Capture questions: name -> k-hat.
CAPTURE_WINDOWS = {"capture_k0": 0, "capture_k2": 2, "capture_k4": 4}
#: Success questions: name -> frame span whose weighted last 3 frames score the trajectory.
SUCCESS_SPANS: dict[str, tuple[int | None, int | None]] = {
    "success_first3": (0, 3),
    "success_first5": (0, 5),
    "success_last3": (None, None),
}
QUESTION_NAMES: tuple[str, ...] = (*CAPTURE_WINDOWS, *SUCCESS_SPANS)
LABELS = {
    "capture_k0": "capture, k-hat = 0",
    "capture_k2": "capture, k-hat = 2",
    "capture_k4": "capture, k-hat = 4",
    "success_first3": "success from first 3 frames",
    "success_first5": "success from first 5 frames",
    "success_last3": "success from last 3 frames",
}
HEADERS = ("capture k=0", "capture k=2", "capture k=4", "success first 3", "success first 5", "success last 3")
BASELINES = ("current_state", "distance", "chance")
#: The lambda grid relative to the task's lambda: 10^(k/2) for k = -6 .. 6.
LAMBDA_FACTORS = tuple(float(10.0 ** (k / 2)) for k in range(-6, 7))
_INTERVALS = tuple(f"{q}{suffix}" for q in QUESTION_NAMES for suffix in ("", "_low", "_high"))
FIELDS = ("task", "method", "budget", *_INTERVALS, "runtime_per_frame_s", "nodes_per_frame", "frames")
DIFFERENCE_FIELDS = ("task", "comparison", "budget", *_INTERVALS)
LAMBDA_FIELDS = ("task", "method", "budget", "lambda", "factor", *_INTERVALS)
#: The tables' files, in each folder that holds them.
TABLE_FILES = ("study.csv", "study_differences.csv", "study_lambda.csv", "study.json")


def study_questions(dataset: Dataset) -> Questions:
    """The six questions of the study on ``dataset``."""
    return Questions(dataset, 3, capture_windows=CAPTURE_WINDOWS, success_spans=SUCCESS_SPANS)


def positive_rates(dataset: Dataset) -> dict[str, float]:
    """Fraction of positive labels of each question: frames for capture, trajectories for success."""
    rates = {name: float(dataset.capture_labels(window).mean()) for name, window in CAPTURE_WINDOWS.items()}
    rates["success"] = float(dataset.success_labels().mean())
    return rates


def method_differences(
    task: str, scored: dict[tuple[str, int], Scored], methods: Sequence[str], expansions: Sequence[int]
) -> list[dict[str, Any]]:
    """EST minus every other tree method at each budget and minus ``distance``, paired, as rows."""
    rows: list[dict[str, Any]] = []
    if "est" not in methods:
        return rows
    for budget in expansions:
        if ("est", budget) not in scored:
            continue
        est = scored[("est", budget)]
        others = [(m, scored[(m, budget)]) for m in methods if m != "est" and (m, budget) in scored]
        if ("distance", 0) in scored:
            others.append(("distance", scored[("distance", 0)]))
        for name, other in others:
            rows.append(
                {"task": task, "comparison": f"est - {name}", "budget": budget, **paired_difference(est, other)}
            )
    return rows


@dataclass
class StudyResult:
    """The study's rows (as written to its files).

    Attributes:
        rows: AP with intervals per task and scorer (tree method at a budget, or baseline).
        differences: paired differences per task, comparison and budget.
        lambdas: AP with intervals per task and lambda.
        meta: settings, positive rates and dataset seeds.

    """

    rows: list[dict[str, Any]] = dataclasses.field(default_factory=list)
    differences: list[dict[str, Any]] = dataclasses.field(default_factory=list)
    lambdas: list[dict[str, Any]] = dataclasses.field(default_factory=list)
    meta: dict[str, Any] = dataclasses.field(default_factory=dict)

    @property
    def tasks(self) -> list[str]:
        """The tasks of the rows, in order."""
        return list(dict.fromkeys(row["task"] for row in self.rows))

    def of_task(self, task: str) -> StudyResult:
        """The rows of ``task`` alone, with the settings and that task's entry of ``meta["tasks"]``."""
        return StudyResult(
            [r for r in self.rows if r["task"] == task],
            [r for r in self.differences if r["task"] == task],
            [r for r in self.lambdas if r["task"] == task],
            {**self.meta, "tasks": {task: self.meta.get("tasks", {}).get(task)}},
        )

    def write(self, out: Path) -> list[Path]:
        """Write the tables of every task under ``out`` and each task's own under ``out/<task>``; their paths.

        A later study of other tasks or budgets in the same ``out`` rewrites ``out/study*`` but
        leaves the per-task tables of tasks it did not run.
        """
        paths = self._write(out, self)
        for task in self.tasks:
            paths += self._write(out / task, self.of_task(task))
        return paths

    @staticmethod
    def _write(out: Path, result: StudyResult) -> list[Path]:
        rows = {"rows": result.rows, "differences": result.differences, "lambdas": result.lambdas}
        return [
            write_csv(out / TABLE_FILES[0], result.rows, FIELDS),
            write_csv(out / TABLE_FILES[1], result.differences, DIFFERENCE_FIELDS),
            write_csv(out / TABLE_FILES[2], result.lambdas, LAMBDA_FIELDS),
            write_json(out / TABLE_FILES[3], {**result.meta, **rows}),
        ]


def format_study(result: StudyResult) -> str:
    """The study's three tables as text: AP, paired differences, AP against lambda."""
    parts = [format_table(result.rows, questions=QUESTION_NAMES, headers=HEADERS, first=("task", "method"))]
    if result.differences:
        parts.append(
            "paired differences (same resamples):\n"
            + format_table(result.differences, questions=QUESTION_NAMES, headers=HEADERS, first=("task", "comparison"))
        )
    if result.lambdas:
        rows = [{**r, "lambda": f"{r['lambda']:.4g}"} for r in result.lambdas]
        parts.append(
            "AP against lambda:\n"
            + format_table(rows, questions=QUESTION_NAMES, headers=HEADERS, first=("task", "method", "lambda"))
        )
    return "\n\n".join(parts)
