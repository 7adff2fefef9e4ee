"""The scooping gripper's scripted servo targets, at one time or at many at once (the same numbers).

The gripper descends to the boxes, closes its fingers, then lifts (`ScoopingConfig`'s phases); each
phase blends in with a C1 cubic. :func:`script_targets` evaluates one time with Python floats (the
roll-out and the one-at-a-time analysis); :func:`script_targets_at` evaluates many with NumPy in the
same operations and order, so every target is the same to the last bit (a batched propagation's).
"""

from __future__ import annotations

import numpy as np

from energy_margin.tasks.scooping_config import ScoopingConfig

__all__ = ["script_targets", "script_targets_at", "smoothstep", "smoothsteps"]


def smoothstep(time: float, start: float, end: float) -> float:
    """0 before ``start``, 1 after ``end``, a C1 cubic in between."""
    if time <= start:
        return 0.0
    if time >= end:
        return 1.0
    u = (time - start) / (end - start)
    return u * u * (3.0 - 2.0 * u)


def smoothsteps(times: np.ndarray, start: float, end: float) -> np.ndarray:
    """:func:`smoothstep` of every time, elementwise (the same operations)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        u = (times - start) / (end - start)
        return np.where(times <= start, 0.0, np.where(times >= end, 1.0, u * u * (3.0 - 2.0 * u)))


def script_targets(config: ScoopingConfig, contact_height: float, closed_travel: float, time: float) -> np.ndarray:
    """Joint targets at ``time`` (s), shape (5,): base height, fingers and blade angles (m, rad)."""
    start = contact_height + config.approach_height
    base = (
        start
        - config.approach_height * smoothstep(time, 0.0, config.approach_end)
        + config.lift_height * smoothstep(time, config.lift_start, config.lift_end)
    )
    finger = closed_travel * smoothstep(time, config.approach_end, config.close_end)
    return np.array([base, finger, config.scoop_angle, finger, config.scoop_angle])


def script_targets_at(
    config: ScoopingConfig, contact_height: float, closed_travel: float, times: np.ndarray
) -> np.ndarray:
    """:func:`script_targets` at every time of ``times`` (k,), shape (k, 5)."""
    start = contact_height + config.approach_height
    base = (
        start
        - config.approach_height * smoothsteps(times, 0.0, config.approach_end)
        + config.lift_height * smoothsteps(times, config.lift_start, config.lift_end)
    )
    finger = closed_travel * smoothsteps(times, config.approach_end, config.close_end)
    targets = np.empty((times.shape[0], 5))
    targets[:, 0], targets[:, 1], targets[:, 3] = base, finger, finger
    targets[:, 2] = targets[:, 4] = config.scoop_angle
    return targets
