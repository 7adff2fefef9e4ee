"""A live alarm calibrated on the live scores themselves: the scored calls of successful episodes.

The conformal guarantee of :mod:`~energy_margin.evaluation.monitor` holds for roll-outs
exchangeable with the calibration ones, scored the same way. ``energy-margin monitor`` calibrates
on an analysed dataset (its trees at the analysis's budget, its success continued along the
recorded motion); a live wrapper scores within a wall-clock budget, and with ``policy=`` continues
success under the user's policy. :func:`calibrate_episodes` calibrates on what the live scorer
itself returned during successful episodes (the dicts of Gymnasium's
``info["energy_margin"]``, or dm_control's ``MarginEnvironment.margins``), so the calibration and
the monitored calls come from one scorer.

Call k of an episode (the reset's call is 0) is its frame k, as :class:`~energy_margin.evaluation.monitor.LiveAlarm`
counts them. A successful episode's nonconformity is the ``persistence``-th smallest watched score
over its calls from ``start_frame`` on; an episode with fewer monitored calls than ``persistence``
cannot raise the alarm and counts as never alarming (its nonconformity is infinite).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from energy_margin.errors import InvalidParameterError, check_choice, check_int
from energy_margin.evaluation.monitor import SCORES, MonitorCalibration, calibrate_grid, watched_score

__all__ = ["calibrate_episodes", "live_scores"]


def live_scores(margin: Mapping[str, Any]) -> tuple[float, float]:
    """The capture and success scores an alarm watches in one live call's dict.

    Capture is the tree's own score (``tree_capture_score``), as the monitor's calibrations take
    it; ``capture_score`` where the tree's is not finite (a learned margin's call).
    """
    capture = float(margin["tree_capture_score"]) if "tree_capture_score" in margin else math.nan
    capture = capture if math.isfinite(capture) else float(margin["capture_score"])
    return capture, float(margin["success_score"])


def calibrate_episodes(
    episodes: Sequence[Sequence[Mapping[str, Any]]],
    success: Sequence[bool] | np.ndarray,
    *,
    alpha: float,
    score: str = "success",
    start_frame: int = 1,
    persistence: int = 1,
) -> MonitorCalibration:
    """Calibrate a live alarm on the scored calls of the successful ``episodes`` (the failed ones are ignored).

    Args:
        episodes: per episode, its scored calls' dicts in order (the reset's first), as the live
            wrappers return them; episodes may differ in length.
        success: whether each episode succeeded, shape (len(episodes),).
        alpha: the false-alarm rate to guarantee on successful episodes scored the same way, in (0, 1).
        score: the watched score, ``success``, ``capture`` or ``min``.
        start_frame: the first monitored call (0: the reset's).
        persistence: how many monitored calls below the threshold raise the alarm, >= 1.

    Returns:
        The calibration (``scorer`` ``margin``) that ``calibration=`` of the live wrappers takes.

    Raises:
        InvalidParameterError: ``success`` of another length than ``episodes``, too few successful
            episodes for ``alpha``, or a threshold no episode reaches (too few of them have
            ``start_frame + persistence`` calls).

    """
    check_choice("score", score, SCORES)
    check_int("start_frame", start_frame, minimum=0)
    check_int("persistence", persistence, minimum=1)
    labels = np.asarray(success, dtype=bool).reshape(-1)
    if labels.size != len(episodes):
        raise InvalidParameterError("success", f"has {labels.size} labels for {len(episodes)} episodes")
    # The successes' watched scores as calibrate_grid's grid, each padded with +inf (a call that never
    # alarms) to the longest episode and to one monitored window at least: an episode too short to
    # alarm gets an infinite nonconformity.
    width = max([len(calls) for calls in episodes] + [start_frame + persistence])
    grid = np.full((len(episodes), width), math.inf)
    for row, (calls, succeeded) in enumerate(zip(episodes, labels.tolist(), strict=True)):
        if succeeded:
            values = [watched_score(score, *live_scores(margin)) for margin in calls]
            grid[row, : len(values)] = values
    found = calibrate_grid(grid, labels, alpha=alpha, start_frame=start_frame, persistence=persistence,
                           scorer="margin", score=score)  # fmt: skip
    if not math.isfinite(found.threshold):
        raise InvalidParameterError(
            "episodes",
            f"hold too few successful ones with {start_frame + persistence} scored calls for a threshold at "
            f"alpha {alpha:g}: score them longer or lower start_frame or persistence",
        )
    return found
