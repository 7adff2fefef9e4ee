"""The tree of one analysed frame, grown again: the analysis's settings and the frame's seed.

``analyze`` stores its resolved settings in ``analysis.json`` and every frame's seed in
``scores.csv``; a tree is a fixed function of those, the frame and the engine, so growing it again
gives the tree the scores were computed from. :func:`analysed_tree` does that and checks that the
scores of the grown tree are the stored ones.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from energy_margin.errors import EnergyMarginError

if TYPE_CHECKING:
    from energy_margin.analysis.frame import FrameScores
    from energy_margin.data.dataset import Dataset
    from energy_margin.planning import CostField
    from energy_margin.world.state import FrameState

__all__ = [
    "AnalysedTree",
    "analysed_tree",
    "analyser_settings",
]


@dataclass(frozen=True)
class AnalysedTree:
    """One frame's tree as the analysis grew it.

    Attributes:
        dataset: the dataset.
        trajectory: trajectory index.
        frame_index: frame index within the trajectory.
        frame: the frame state.
        field: the energy-cost field of the tree.
        likelihoods: likelihood of every node, shape (M,).
        scores: scores of the grown tree.
        stored: ``capture_score`` and ``success_score`` of ``scores.csv`` for the frame.
        likelihood_lambda: the analysis's lambda, 1/J.

    """

    dataset: Dataset
    trajectory: int
    frame_index: int
    frame: FrameState
    field: CostField
    likelihoods: np.ndarray
    scores: FrameScores
    stored: dict[str, float]
    likelihood_lambda: float

    @property
    def matches_stored(self) -> bool:
        """Whether the grown tree's scores equal the stored ones (to 1e-9)."""
        return bool(
            abs(self.scores.capture_score - self.stored["capture_score"]) <= 1e-9
            and abs(self.scores.success_score - self.stored["success_score"]) <= 1e-9
        )


def analyser_settings(directory: Path) -> dict[str, Any]:
    """The analyzer settings of ``analysis.json`` in a dataset directory, later fields as they were then.

    A field the file predates takes the behaviour it had when the file was written
    (:func:`~energy_margin.analysis.run.recorded_analyzer`), so the tree grows again as it grew.
    """
    from energy_margin.analysis.frame import AnalyzerConfig
    from energy_margin.analysis.run import recorded_analyzer, resolved_continuation
    from energy_margin.data.scores_file import CONFIG_FILE
    from energy_margin.runs.files import read_json

    description = read_json(directory / CONFIG_FILE, what="analysis record")
    analyzer = description.get("analyzer") if isinstance(description, dict) else None
    if not isinstance(analyzer, dict):
        raise EnergyMarginError(f"{directory / CONFIG_FILE}: no 'analyzer' settings")
    settings = recorded_analyzer(analyzer)
    settings["continuation"] = resolved_continuation(description)  # the default rule's decision, where it decided
    known = set(AnalyzerConfig().to_dict())
    return {key: value for key, value in settings.items() if key in known}


def analysed_tree(directory: Path | str, trajectory: int, frame_index: int) -> AnalysedTree:
    """Grow the tree of frame ``frame_index`` of ``trajectory`` again, as ``analyze`` grew it.

    Raises:
        EnergyMarginError: the dataset does not load, has no scores (run ``analyze`` first), or
            has no such trajectory or frame.

    """
    from energy_margin.analysis.frame import AnalyzerConfig, analyze_frame
    from energy_margin.analysis.scores import likelihood
    from energy_margin.data.dataset import load_dataset
    from energy_margin.data.scores_file import load_scores
    from energy_margin.report.render import check_trajectory

    directory = Path(directory)
    dataset = load_dataset(directory)
    check_trajectory(dataset, trajectory, frame_index)
    scores = load_scores(directory)
    rows = np.flatnonzero((scores["trajectory"] == trajectory) & (scores["frame"] == frame_index))
    if rows.size != 1:
        raise EnergyMarginError(
            f"{directory}: scores.csv has {rows.size} rows for trajectory {trajectory}, "
            f"frame {frame_index} (expected 1)"
        )
    row = int(rows[0])
    try:
        config = AnalyzerConfig(**analyser_settings(directory))
    except (TypeError, ValueError) as error:
        raise EnergyMarginError(f"{directory}: analysis.json has bad analyzer settings ({error})") from None
    task = dataset.task
    lam = config.likelihood_lambda if config.likelihood_lambda is not None else task.config.likelihood_lambda
    frame = dataset.frame(trajectory, frame_index)
    grown, field = analyze_frame(
        task,
        frame,
        friction=float(dataset.arrays["friction"][trajectory]),
        drive=dataset.arrays["drive"][trajectory],
        seed=int(scores["seed"][row]),
        config=config,
        start_time=float(dataset.arrays["frame_time"][trajectory, frame_index]),
    )
    stored = {name: float(scores[name][row]) for name in ("capture_score", "success_score")}
    return AnalysedTree(
        dataset, trajectory, frame_index, frame, field, likelihood(field.costs, lam), grown, stored, float(lam)
    )
