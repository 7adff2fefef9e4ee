"""Active selection of the frames to analyse: an ensemble's disagreement on the unselected pool.

:func:`select_uncertain` fits :func:`ensemble_member` regressors on bootstrap resamples of the
selected frames and picks the candidates of largest :func:`disagreement`, a fraction at random.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from energy_margin.errors import (
    InvalidParameterError,
    check_float,
    check_int,
)

__all__ = ["MemberFit", "disagreement", "ensemble_member", "select_uncertain"]


#: Fits one ensemble member: ``fit_member(features (F, D), targets (F, 2), seed)`` -> a regressor.
MemberFit = Callable[[np.ndarray, np.ndarray, int], Any]


def disagreement(predictions: np.ndarray) -> np.ndarray:
    """Disagreement of an ensemble on each frame: std over members of capture plus that of success.

    Args:
        predictions: shape (M, F, 2), the M members' capture and success scores of F frames.

    Returns:
        Shape (F,).
    """
    predictions = np.asarray(predictions, dtype=float)
    if predictions.ndim != 3 or predictions.shape[2] != 2:
        raise InvalidParameterError("predictions", f"must have shape (members, frames, 2), got {predictions.shape}")
    return predictions.std(axis=0).sum(axis=1)


def select_uncertain(
    features: np.ndarray,
    targets: np.ndarray,
    selected: np.ndarray,
    candidates: np.ndarray,
    count: int,
    *,
    members: int,
    seed: np.random.SeedSequence | int,
    random_fraction: float = 0.0,
    fit_member: MemberFit | None = None,
) -> np.ndarray:
    """Pick ``count`` of ``candidates`` by the disagreement of an ensemble fitted on ``selected``.

    Each of the ``members`` members is fitted by ``fit_member`` on a bootstrap resample of the
    ``selected`` rows (their ``targets`` are the revealed scores); the members predict every
    candidate, and the ``count - round(random_fraction * count)`` candidates of largest
    :func:`disagreement` are taken (ties: the earlier candidate first), then the rest of
    ``count`` drawn uniformly from the other candidates.

    Args:
        features: features of every pool frame, shape (P, D).
        targets: capture and success scores, shape (P, 2); only the ``selected`` rows are read.
        selected: pool rows already selected, shape (S,), S >= 1.
        candidates: pool rows that may be picked, shape (C,), in tie-breaking order.
        count: frames to pick, 1 <= count <= C.
        members: ensemble size, >= 2.
        seed: seeds the bootstrap resamples, the members and the random part.
        random_fraction: fraction of ``count`` drawn at random, in [0, 1].
        fit_member: fits one member (default: :func:`ensemble_member` of 40 rounds).

    Returns:
        The picked pool rows, shape (count,): the uncertain ones by decreasing disagreement, then
        the random ones.
    """
    selected = np.asarray(selected, dtype=np.int64)
    candidates = np.asarray(candidates, dtype=np.int64)
    check_int("count", count, minimum=1, maximum=len(candidates))
    check_int("members", members, minimum=2)
    check_float("random_fraction", random_fraction, minimum=0.0, maximum=1.0)
    if len(selected) == 0:
        raise InvalidParameterError("selected", "must hold at least one row")
    fit = fit_member if fit_member is not None else ensemble_member(40)
    sequence = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
    rng = np.random.default_rng(sequence)
    member_seeds = sequence.generate_state(members, np.uint32)
    candidate_x = features[candidates]
    predictions = np.empty((members, len(candidates), 2))
    for m in range(members):
        rows = selected[rng.integers(0, len(selected), size=len(selected))]
        model = fit(features[rows], targets[rows], int(member_seeds[m]))
        predictions[m] = np.clip(model.predict(candidate_x), 0.0, 1.0)
    n_random = min(count, round(random_fraction * count))
    ranked = np.argsort(-disagreement(predictions), kind="stable")
    uncertain = ranked[: count - n_random]
    rest = np.setdiff1d(np.arange(len(candidates)), uncertain)
    randomly = rng.choice(rest, size=n_random, replace=False) if n_random else np.empty(0, dtype=np.int64)
    return candidates[np.concatenate([uncertain, randomly]).astype(np.int64)]


def ensemble_member(rounds: int) -> MemberFit:
    """A cheap ensemble member: per score, boosted trees of ``rounds`` rounds and depth 3.

    scikit-learn's ``HistGradientBoostingRegressor`` (learning rate 0.2, no early stopping) with
    leaves of at least ``max(1, min(20, F // 10))`` of the F frames it is fitted on (scikit-learn's
    default of 20 would leave a member fitted on a few dozen frames without a split), on one
    thread as :func:`~energy_margin.learning.regressors.fit_regressor` fits.
    """

    def fit(features: np.ndarray, targets: np.ndarray, seed: int) -> _Member:
        from sklearn.ensemble import HistGradientBoostingRegressor
        from threadpoolctl import threadpool_limits

        leaf = max(1, min(20, len(features) // 10))
        with threadpool_limits(limits=1):
            models = [
                HistGradientBoostingRegressor(
                    max_iter=rounds,
                    learning_rate=0.2,
                    max_depth=3,
                    min_samples_leaf=leaf,
                    early_stopping=False,
                    random_state=seed,
                ).fit(features, targets[:, output])
                for output in range(2)
            ]
        return _Member(models)

    return fit


class _Member:
    """Predictions of one fitted model per score, shape (F, 2)."""

    def __init__(self, models: list[Any]) -> None:
        self.models = models

    def predict(self, features: np.ndarray) -> np.ndarray:
        from threadpoolctl import threadpool_limits

        with threadpool_limits(limits=1):
            return np.stack([model.predict(features) for model in self.models], axis=1)
