"""What the learn pipeline made: its model and report, and the sets it generated and analysed."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from energy_margin.learning.margin_model import MarginModel, MarginModelReport

__all__ = ["LearnResult", "LearnSet"]


@dataclass(frozen=True)
class LearnSet:
    """One generated and analysed dataset of the pipeline.

    Attributes:
        name: its folder under ``WORK/sets`` (``objects-10``, ``scene``).
        objects: objects per scene.
        directory: the dataset directory.
        generation_seed: the seed it was generated with.
        analysis_seed: the seed it was analysed with.
        generated: this call generated it (``False``: it was there from an earlier run).
        analysed: this call scored frames of it (``False``: its scores.csv was complete).

    """

    name: str
    objects: int
    directory: Path
    generation_seed: int
    analysis_seed: int
    generated: bool
    analysed: bool

    def to_dict(self) -> dict[str, Any]:
        """The set as JSON values."""
        return {
            "name": self.name,
            "objects": self.objects,
            "directory": str(self.directory),
            "generation_seed": self.generation_seed,
            "analysis_seed": self.analysis_seed,
            "generated": self.generated,
            "analysed": self.analysed,
        }


@dataclass(frozen=True)
class LearnResult:
    """What :func:`~energy_margin.learning.pipeline.learn_pipeline` made.

    Attributes:
        model: the fitted model (also written to ``out`` and ``WORK/model.npz``).
        report: :func:`~energy_margin.learning.margin_model.fit_margin_model`'s held-out report.
        out: the model file written.
        work: the work directory.
        sets: the datasets, in the order of ``objects``.
        fit_seed: the seed of the fit.
        resumed: the work directory held this very run before the call.
        seconds: wall time of the call.

    """

    model: MarginModel
    report: MarginModelReport
    out: Path
    work: Path
    sets: tuple[LearnSet, ...]
    fit_seed: int
    resumed: bool
    seconds: float
