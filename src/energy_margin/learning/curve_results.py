"""The results of a learning curve: held-out AP per question, one point per size, the curve.

:class:`LearningCurve` holds one :class:`CurvePoint` per size (see :mod:`energy_margin.learning.curve`
for the protocol); both have a JSON-compatible ``to_dict``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from energy_margin._version import __version__

__all__ = ["CurvePoint", "FrameId", "LearningCurve", "QuestionAp"]


#: One frame: (dataset index, trajectory, frame index).
FrameId = tuple[int, int, int]


@dataclass(frozen=True)
class QuestionAp:
    """Held-out Average Precision of one question: the learned margin's beside the tree's.

    Both are ``None`` when the held-out labels of the question hold a single class.
    """

    learned: float | None
    tree: float | None


@dataclass(frozen=True)
class CurvePoint:
    """One point of a learning curve: a fit of the margin on ``frames`` selected pool frames.

    Attributes:
        frames: frames used, i.e. trees grown.
        trajectories: distinct trajectories those frames come from.
        ap: held-out AP of each question of :data:`QUESTIONS`.
        r2_capture: held-out R² of the capture score (``None`` when the truth is constant).
        r2_success: held-out R² of the success score (``None`` likewise).
        fit_seconds: wall time of the reported fit.
        selection_seconds: wall time of the ensemble fits and predictions so far (0 for random).
        selected: the frames used, sorted.
    """

    frames: int
    trajectories: int
    ap: dict[str, QuestionAp]
    r2_capture: float | None
    r2_success: float | None
    fit_seconds: float
    selection_seconds: float
    selected: tuple[FrameId, ...] = field(repr=False)

    def to_dict(self, *, selected: bool = False) -> dict[str, Any]:
        """JSON-compatible form (the selected frames only when asked: they are many)."""
        out: dict[str, Any] = {
            "frames": self.frames,
            "trajectories": self.trajectories,
            "ap": {question: {"learned": v.learned, "tree": v.tree} for question, v in self.ap.items()},
            "r2": {"capture": self.r2_capture, "success": self.r2_success},
            "fit_seconds": self.fit_seconds,
            "selection_seconds": self.selection_seconds,
        }
        if selected:
            out["selected"] = [list(frame) for frame in self.selected]
        return out


@dataclass(frozen=True)
class LearningCurve:
    """A learning curve: one :class:`CurvePoint` per size, on fixed held-out trajectories.

    Attributes:
        kind: regressor kind of the reported fits.
        strategy: ``"random"`` or ``"uncertainty"``.
        seed: the seed given.
        holdout: fraction of the trajectories held out.
        success_frames: k-bar of the trajectory success AP.
        sizes: the sizes asked for.
        initial: random frames the uncertainty selection starts from (``None`` for random).
        ensemble: members of the selection ensemble (``None`` for random).
        ensemble_rounds: boosting rounds of each member (``None`` for random).
        random_fraction: fraction of each selected batch drawn at random (``None`` for random).
        batch: most frames added per ensemble fit (``None``: up to the next size).
        options: the reported fits' regressor options.
        pool_frames: frames of the training pool.
        pool_trajectories: trajectories of the training pool.
        held_out: the held-out ``(dataset, trajectory)`` pairs, sorted.
        held_out_frames: frames of the held-out trajectories.
        points: one per size, in order.
        reference: the fit on the whole pool, when asked for.
    """

    kind: str
    strategy: str
    seed: int
    holdout: float
    success_frames: int
    sizes: tuple[int, ...]
    initial: int | None
    ensemble: int | None
    ensemble_rounds: int | None
    random_fraction: float | None
    batch: int | None
    options: dict[str, Any]
    pool_frames: int
    pool_trajectories: int
    held_out: tuple[tuple[int, int], ...]
    held_out_frames: int
    points: tuple[CurvePoint, ...]
    reference: CurvePoint | None

    def to_dict(self, *, selected: bool = False) -> dict[str, Any]:
        """JSON-compatible form."""
        return {
            "kind": self.kind,
            "strategy": self.strategy,
            "seed": self.seed,
            "holdout": self.holdout,
            "success_frames": self.success_frames,
            "sizes": list(self.sizes),
            "initial": self.initial,
            "ensemble": self.ensemble,
            "ensemble_rounds": self.ensemble_rounds,
            "random_fraction": self.random_fraction,
            "batch": self.batch,
            "options": {key: _plain(value) for key, value in self.options.items()},
            "pool_frames": self.pool_frames,
            "pool_trajectories": self.pool_trajectories,
            "held_out": [list(pair) for pair in self.held_out],
            "held_out_frames": self.held_out_frames,
            "points": [point.to_dict(selected=selected) for point in self.points],
            "reference": None if self.reference is None else self.reference.to_dict(selected=False),
            "package_version": __version__,
        }


def _plain(value: Any) -> Any:
    """A JSON-compatible copy of an option value (tuples and arrays as lists)."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, tuple | list):
        return [_plain(item) for item in value]
    return value
