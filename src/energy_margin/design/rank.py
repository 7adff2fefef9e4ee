"""The statistics of a design sweep: per-trajectory outcomes, and how the margins rank the designs.

:func:`design_outcome` reads one analysed design into per-trajectory arrays (its labels and its
mean capture, success and early success scores); :func:`rank_correlations` gives Spearman's rho of
each margin column against the success rate across designs, with a permutation p-value and an
interval from paired trajectory resamples; :func:`rank_convergence` asks how that rank agreement
grows with the number of trajectories the estimates are computed from.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from energy_margin.analysis.scores import trajectory_success_score
from energy_margin.data.dataset import Dataset
from energy_margin.evaluation.metrics import score_grid
from energy_margin.evaluation.statistics import spearman, spearman_rho

__all__ = [
    "EARLY_SUCCESS_FRAMES",
    "MARGINS",
    "MARGIN_LABELS",
    "DesignOutcome",
    "default_trajectory_counts",
    "design_outcome",
    "rank_convergence",
    "rank_correlations",
]

#: k-bar of the early success prediction (as ``evaluate`` and ``budget``).
EARLY_SUCCESS_FRAMES = 3
#: The margin columns ranked against the success rate, first the one that matters most.
MARGINS = ("early_success_score", "success_score", "capture_score")
MARGIN_LABELS = {
    "early_success_score": "early success score (first half)",
    "success_score": "success score (all frames)",
    "capture_score": "capture score (all frames)",
}


@dataclass(frozen=True)
class DesignOutcome:
    """Per-trajectory values of one analysed design (T = trajectories).

    Attributes:
        success: success label of every trajectory, shape (T,).
        capture_score: mean capture score of each trajectory's frames, shape (T,).
        success_score: mean success score of each trajectory's frames, shape (T,).
        early_success_score: early success prediction of each trajectory, shape (T,).
        runtime_per_frame_s: mean analysis time of a frame, s.

    """

    success: np.ndarray
    capture_score: np.ndarray
    success_score: np.ndarray
    early_success_score: np.ndarray
    runtime_per_frame_s: float

    def column(self, name: str) -> np.ndarray:
        """The per-trajectory array of ``name`` (``"success"`` or a :data:`MARGINS` entry)."""
        return np.asarray(getattr(self, name), dtype=float)


def design_outcome(dataset: Dataset, scores: dict[str, np.ndarray]) -> DesignOutcome:
    """The per-trajectory values of a dataset and its ``scores.csv`` columns."""
    capture = score_grid(dataset, scores, "capture_score")
    success = score_grid(dataset, scores, "success_score")
    half = max(1, dataset.n_frames // 2)
    return DesignOutcome(
        success=dataset.success_labels().astype(bool),
        capture_score=capture.mean(axis=1),
        success_score=success.mean(axis=1),
        early_success_score=trajectory_success_score(success[:, :half], last=EARLY_SUCCESS_FRAMES),
        runtime_per_frame_s=float(np.mean(scores["runtime_s"])),
    )


def _rates(outcomes: Sequence[DesignOutcome], rows: np.ndarray) -> np.ndarray:
    return np.array([o.column("success")[rows].mean() for o in outcomes])


def _means(outcomes: Sequence[DesignOutcome], name: str, rows: np.ndarray) -> np.ndarray:
    return np.array([o.column(name)[rows].mean() for o in outcomes])


def rank_correlations(
    outcomes: Sequence[DesignOutcome], *, seed: int = 0, bootstrap: int = 2000
) -> dict[str, dict[str, Any]]:
    """Spearman's rho of each margin column against the success rate across designs.

    Every entry has ``rho``, its permutation ``p_value`` (``exact`` when every ordering was
    enumerated), ``n`` designs and a 95 % percentile interval ``low``/``high`` over ``bootstrap``
    resamples of the trajectory indices, the same indices for every design (the designs share
    their trajectories' random draws); resamples where rho is undefined (a constant column) are
    left out and ``bootstrap_defined`` counts the others.
    """
    n_trajectories = outcomes[0].success.size
    everything = np.arange(n_trajectories)
    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(2)[0])
    resamples = rng.integers(0, n_trajectories, (bootstrap, n_trajectories))
    rates = _rates(outcomes, everything)
    result: dict[str, dict[str, Any]] = {}
    for name in MARGINS:
        correlation = spearman(_means(outcomes, name, everything), rates, seed=seed)
        samples = [spearman_rho(_means(outcomes, name, rows), _rates(outcomes, rows)) for rows in resamples]
        defined = [value for value in samples if value is not None]
        low, high = (float(v) for v in np.percentile(defined, [2.5, 97.5])) if defined else (None, None)
        result[name] = {
            "rho": correlation.rho,
            "p_value": correlation.p_value,
            "exact": correlation.exact,
            "n": correlation.n,
            "low": low,
            "high": high,
            "bootstrap_defined": len(defined),
        }
    return result


def default_trajectory_counts(n_trajectories: int) -> list[int]:
    """The t of the convergence table: 1, 2, 3, 5, 10, 15, 20, 30, 50, ... up to T, and T."""
    counts = [t for t in (1, 2, 3, 5, 10, 15, 20, 30, 50, 100, 200, 500) if t < n_trajectories]
    return [*counts, n_trajectories]


def rank_convergence(
    outcomes: Sequence[DesignOutcome], counts: Sequence[int], *, subsets: int = 200, seed: int = 0
) -> list[dict[str, Any]]:
    """Rank agreement with the success rate of all T trajectories when only t of them are used.

    For each t, ``subsets`` random sets of t trajectory indices (the same set for every design)
    give each design's margin means and success rate on those trajectories; each row reports, per
    margin column and for the success rate itself (``success_rate``), the mean over the subsets of
    Spearman's rho against the success rate of all T trajectories, and how many subsets had a
    defined rho (``<name>_defined``); a subset whose estimate is the same for every design (e.g. t
    = 1 with every design failing it) ranks nothing and counts as rho = 0 in the mean (``None``
    when no subset has a defined rho: the reference rates are all equal). At t = T there is one
    subset, all trajectories.
    """
    n_trajectories = outcomes[0].success.size
    reference = _rates(outcomes, np.arange(n_trajectories))
    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(2)[1])
    rows: list[dict[str, Any]] = []
    for t in counts:
        if t == n_trajectories:
            chosen = [np.arange(n_trajectories)]
        else:
            chosen = [np.sort(rng.choice(n_trajectories, size=t, replace=False)) for _ in range(subsets)]
        row: dict[str, Any] = {"trajectories": int(t), "subsets": len(chosen)}
        for name in (*MARGINS, "success_rate"):
            values = []
            for indices in chosen:
                estimate = _rates(outcomes, indices) if name == "success_rate" else _means(outcomes, name, indices)
                values.append(spearman_rho(estimate, reference))
            defined = [value for value in values if value is not None]
            # An estimate that ties every design ranks nothing: it counts as rho = 0.
            row[name] = float(np.mean([0.0 if value is None else value for value in values])) if defined else None
            row[f"{name}_defined"] = len(defined)
        rows.append(row)
    return rows
