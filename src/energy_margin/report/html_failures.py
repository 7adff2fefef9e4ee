"""The report's account of failed trajectories: which object left which region, at which frame and where.

One table per task from :func:`energy_margin.evaluation.explain.explain_failures` on the dataset
the report's Table I evaluated; ``energy-margin evaluate DIR --explain`` prints the same account.
"""

from __future__ import annotations

import html

from energy_margin.data.dataset import Dataset
from energy_margin.evaluation.explain import event_words, explain_failures
from energy_margin.report.html_parts import _table

__all__ = ["failures_html"]

#: Rows of a task's table at most; the paragraph above it says how many there are.
MAX_ROWS = 20


def failures_html(task: str, dataset: Dataset, *, max_rows: int = MAX_ROWS) -> str:
    """A paragraph and a table: each failed trajectory's objects outside a region, the frame, time and position.

    Args:
        task: the task's name, for the caption.
        dataset: the evaluated dataset.
        max_rows: rows shown at most (>= 1); the rest are counted.

    """
    explanations = explain_failures(dataset)
    name = html.escape(task)
    if not explanations:
        return f"<p>{name}: every trajectory succeeded.</p>"
    rows = []
    for item in explanations:
        for event in item.events:
            what = event_words(event)
            x, y, z = event.position
            rows.append(
                [item.trajectory, event.name, what, event.frame, f"{event.time_s:.3f}", f"({x:.3f}, {y:.3f}, {z:.3f})"]
            )
    shown = f"the first {max_rows} of {len(rows)} rows" if len(rows) > max_rows else f"all {len(rows)} rows"
    caption = (
        f"<p>{name}: {len(explanations)} of {dataset.n_trajectories} trajectories failed; each object's first frame "
        f"outside the capture region and each object outside the success region at the last frame ({shown}; "
        "<code>energy-margin evaluate DIR --explain</code> lists every one).</p>"
    )
    header = ["trajectory", "object", "what", "frame", "time (s)", "position (m)"]
    return caption + _table(header, rows[:max_rows])
