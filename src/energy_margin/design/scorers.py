"""What a design search is given: a :class:`Scorer` of a design's frames and a :class:`Verifier` of its episodes.

The tree scorer of ``analyze`` is here (:class:`TreeScorer`); the learned one is
:class:`energy_margin.learning.scoring.LearnedFrameScorer` and the episode verifier
:class:`energy_margin.design.verification.EpisodeVerifier`.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.run import analyze
from energy_margin.tasks import Task

__all__ = ["DESIGN_EXPANSIONS", "DESIGN_FRAMES", "DESIGN_TRAJECTORIES", "Scorer", "TreeScorer", "Verifier"]

#: Expansions per frame of a design's trees by default (``design --expansions``): a search scores
#: many designs, and ranks them as well at 100 as at 300 on the tasks' families (docs/howto/design.md).
DESIGN_EXPANSIONS = 100
#: Roll-outs of one evaluation of a design, and frames per roll-out, by default (``design
#: --trajectories``, ``--frames``; ``design_search``'s ``n_trajectories``, ``n_frames``).
DESIGN_TRAJECTORIES = 5
DESIGN_FRAMES = 10


class Scorer(Protocol):
    """Scores every frame of a dataset directory: writes its ``scores.csv``."""

    def settings(self) -> dict[str, Any]:
        """What decides the scores (saved in ``design.json`` under ``objective``)."""

    def score(self, directory: Path, *, seed: int, workers: int) -> None:
        """Write ``scores.csv`` in ``directory`` (resuming what is there)."""


class Verifier(Protocol):
    """Runs closed-loop episodes of a design."""

    def settings(self) -> dict[str, Any]:
        """What decides the episodes besides design, level and seeds (saved under ``verify``)."""

    def check(self, task: Task, levels: Sequence[str], *, n_objects: int) -> None:
        """Refuse a task (its fixed settings applied), a scene or a level it cannot run, before anything is written."""

    def successes(
        self,
        task: Task,
        overrides: dict[str, Any],
        *,
        n_objects: int,
        level: str,
        seeds: Sequence[tuple[int, np.random.SeedSequence]],
        workers: int = 1,
    ) -> Iterator[tuple[int, bool]]:
        """``(index, success)`` of each episode of ``task.configured(overrides)``, in any order."""


@dataclass(frozen=True)
class TreeScorer:
    """The energy margin of ``analyze``: a tree of ``analyzer.expansions`` expansions per frame.

    By default :data:`DESIGN_EXPANSIONS`, as on the command line.
    """

    analyzer: AnalyzerConfig = field(default_factory=lambda: AnalyzerConfig(expansions=DESIGN_EXPANSIONS))

    def settings(self) -> dict[str, Any]:
        """``{"kind": "margin", "analyzer": ...}``."""
        return {"kind": "margin", "analyzer": self.analyzer.fixed_continuation().to_dict()}

    def score(self, directory: Path, *, seed: int, workers: int) -> None:
        """``analyze`` the dataset (its journal resumes an interrupted analysis)."""
        analyze(directory, self.analyzer.fixed_continuation(), seed=seed, workers=workers, progress=False)
