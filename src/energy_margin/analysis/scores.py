"""Algorithm 1: likelihood of reached states and the capture and success scores."""

from __future__ import annotations

import numpy as np

from energy_margin.errors import InvalidParameterError, check_choice, check_float, check_positive_int

__all__ = [
    "CAPTURE_GATES",
    "gate_capture",
    "likelihood",
    "region_score",
    "trajectory_success_score",
    "trajectory_weights",
]


#: What a frame whose own state is not captured scores for capture (``AnalyzerConfig.capture_gate``).
CAPTURE_GATES = ("current", "none")


def gate_capture(capture: float, captured_now: bool, gate: str) -> float:
    """The capture score of a frame, gated by whether the frame itself is captured.

    Args:
        capture: the tree's capture score (eq. 2), in [0, 1].
        captured_now: whether the frame's own objects lie in its capture region
            (:meth:`~energy_margin.tasks.Task.is_captured`, the label at k-hat 0).
        gate: ``"current"``: 0 when the frame is not captured (its objects are out of the capture
            region already, so no perturbation is needed to lose them), else ``capture``;
            ``"none"``: ``capture`` as it is (the paper's score).

    """
    check_choice("capture_gate", gate, CAPTURE_GATES)
    return capture if captured_now or gate == "none" else 0.0


def likelihood(costs: np.ndarray, lam: float) -> np.ndarray:
    """Softmax likelihood ``L_m = exp(-lam (c_m - c_min)) / sum_j exp(-lam (c_j - c_min))`` (eq. 1).

    Computed with the log-sum-exp shift, so any cost scale (up to 1e6 J and beyond) stays finite.

    Args:
        costs: energy costs of the tree's nodes, shape (M,), J; finite.
        lam: inverse temperature lambda, 1/J, >= 0.

    Returns:
        Likelihoods, shape (M,), summing to 1.

    """
    costs = np.asarray(costs, dtype=float)
    if costs.ndim != 1 or costs.size == 0:
        raise InvalidParameterError("costs", f"must be a non-empty 1-D array, got shape {costs.shape}")
    if not np.all(np.isfinite(costs)):
        raise InvalidParameterError("costs", "must be finite")
    check_float("lam", lam, minimum=0.0)
    logits = -lam * (costs - costs.min())
    logits -= logits.max()
    weights = np.exp(logits)
    return weights / weights.sum()


def region_score(costs: np.ndarray, inside: np.ndarray, lam: float) -> float:
    """Likelihood mass of the nodes inside a set (eq. 2 and 3).

    Args:
        costs: node costs, shape (M,), J.
        inside: whether each node lies in the set, shape (M,), bool.
        lam: inverse temperature, 1/J.

    """
    inside = np.asarray(inside, dtype=bool)
    if inside.shape != np.shape(costs):
        raise InvalidParameterError("inside", f"must have shape {np.shape(costs)}, got {inside.shape}")
    # Rounding can push a sum of likelihoods that should be exactly 1 just above it.
    return min(1.0, float(np.sum(likelihood(costs, lam)[inside])))


def trajectory_weights(n_frames: int, *, last: int, scheme: str = "linear") -> np.ndarray:
    """Weights of a trajectory's frames for the trajectory-level success score.

    Args:
        n_frames: number of frames K.
        last: the score averages the last ``last`` frames (k-bar), 1 <= last.
        scheme: ``"linear"`` (weights 1, 2, ..., k-bar increasing towards the end) or ``"uniform"``.

    Returns:
        Weights, shape (n_frames,), zero before the window, summing to 1.

    """
    check_positive_int("last", last)
    check_choice("scheme", scheme, ("linear", "uniform"))
    window = min(last, n_frames)
    weights = np.zeros(n_frames)
    if scheme == "linear":
        weights[n_frames - window :] = np.arange(1, window + 1, dtype=float)
    else:
        weights[n_frames - window :] = 1.0
    return weights / weights.sum()


def trajectory_success_score(frame_scores: np.ndarray, *, last: int, scheme: str = "linear") -> np.ndarray:
    """Weighted average of the last ``last`` frame success scores of every trajectory.

    Args:
        frame_scores: success scores, shape (n_trajectories, n_frames).
        last: k-bar, the number of final frames averaged.
        scheme: ``"linear"`` or ``"uniform"`` weights.

    Returns:
        Scores, shape (n_trajectories,).

    """
    frame_scores = np.asarray(frame_scores, dtype=float)
    return frame_scores @ trajectory_weights(frame_scores.shape[1], last=last, scheme=scheme)
