"""The run layer: what every long command is built on.

A run directory with its resolved settings, one rule for resuming and ``--overwrite``, and an
exclusive writer's lock (:mod:`~energy_margin.runs.directory`, :mod:`~energy_margin.runs.lock`);
the append-only journal (:mod:`~energy_margin.runs.journal`); the progress bar
(:mod:`~energy_margin.runs.progress`); result tables written as CSV and JSON and printed as text
(:mod:`~energy_margin.runs.tables`); figures as display objects built from a result
(:mod:`~energy_margin.runs.display`).
"""

from energy_margin.runs.directory import RunDirectory, RunSpec, open_run, run_directory
from energy_margin.runs.journal import Journal
from energy_margin.runs.lock import RunLock, RunLockedError
from energy_margin.runs.progress import Progress, progress_bar

__all__ = [
    "Journal",
    "Progress",
    "RunDirectory",
    "RunLock",
    "RunLockedError",
    "RunSpec",
    "open_run",
    "progress_bar",
    "run_directory",
]
