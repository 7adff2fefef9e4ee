"""What the controller's model does not know: the real friction, pushes on objects, observation noise.

An episode runs on a plant whose friction is drawn from a range wider than the controller's
nominal value, whose objects are pushed at random times, and whose object positions reach the
controller with noise. The levels are named so that results can be compared across runs.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from energy_margin.errors import EnergyMarginError

__all__ = [
    "DISTURBANCES",
    "Disturbance",
    "Push",
    "draw_plant",
    "get_disturbance",
    "observe",
    "push_wrenches",
]


@dataclass(frozen=True)
class Disturbance:
    """One disturbance level.

    Attributes:
        name: the level's name.
        friction_scale: the plant's Coulomb coefficient is the nominal one times a factor drawn
            log-uniformly in [1 / friction_scale, friction_scale] (1: the nominal friction).
        push_rate: mean number of pushes per second (a Poisson process over the episode), 1/s.
        push_speed: speed change of a pushed object, m/s, in a uniformly random planar direction.
        push_duration: a push is a constant force held this long, s.
        position_noise: standard deviation of the noise on each observed object coordinate, m.

    """

    name: str
    friction_scale: float = 1.0
    push_rate: float = 0.0
    push_speed: float = 0.0
    push_duration: float = 0.05
    position_noise: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        """The level as a JSON-ready dict."""
        return asdict(self)


#: The levels offered by ``energy-margin control --disturbance``.
DISTURBANCES: dict[str, Disturbance] = {
    "none": Disturbance("none"),
    "mild": Disturbance("mild", friction_scale=1.5, push_rate=0.5, push_speed=0.1, position_noise=0.002),
    "hard": Disturbance("hard", friction_scale=2.5, push_rate=1.5, push_speed=0.3, position_noise=0.005),
}


def get_disturbance(name: str) -> Disturbance:
    """The level ``name``; one clear error for an unknown one."""
    if name not in DISTURBANCES:
        raise EnergyMarginError(f"unknown disturbance {name!r}; choose one of {', '.join(DISTURBANCES)}")
    return DISTURBANCES[name]


@dataclass(frozen=True)
class Push:
    """One push: object ``target`` gets ``force`` (N, world x and y) from ``start`` for ``duration`` s."""

    start: float
    duration: float
    target: int
    force: np.ndarray


def draw_plant(
    disturbance: Disturbance,
    rng: np.random.Generator,
    *,
    nominal_friction: float,
    duration: float,
    masses: np.ndarray,
) -> tuple[float, list[Push]]:
    """The plant's friction and its pushes over an episode of ``duration`` seconds.

    Args:
        disturbance: the level.
        rng: the episode's generator for the plant.
        nominal_friction: the controller's Coulomb coefficient.
        duration: episode length, s.
        masses: object masses, shape (n_objects,), kg.

    """
    factor = float(np.exp(rng.uniform(-1.0, 1.0) * np.log(disturbance.friction_scale)))
    pushes: list[Push] = []
    if disturbance.push_rate > 0 and disturbance.push_speed > 0:
        count = int(rng.poisson(disturbance.push_rate * duration))
        for start in np.sort(rng.uniform(0.0, duration, count)):
            target = int(rng.integers(len(masses)))
            angle = float(rng.uniform(0.0, 2.0 * np.pi))
            magnitude = masses[target] * disturbance.push_speed / disturbance.push_duration
            force = magnitude * np.array([np.cos(angle), np.sin(angle)])
            pushes.append(Push(float(start), disturbance.push_duration, target, force))
    return nominal_friction * factor, pushes


def push_wrenches(pushes: list[Push], time: float, n_objects: int) -> np.ndarray:
    """World wrenches (n_objects, 6) of the pushes active at ``time`` (s)."""
    wrenches = np.zeros((n_objects, 6))
    for push in pushes:
        if push.start <= time < push.start + push.duration:
            wrenches[push.target, :2] += push.force
    return wrenches


def observe(positions: np.ndarray, disturbance: Disturbance, rng: np.random.Generator) -> np.ndarray:
    """Object positions (n_objects, 3) as the controller sees them: with noise in x and y."""
    noisy = np.array(positions, dtype=float)
    if disturbance.position_noise > 0:
        noisy[:, :2] += rng.normal(0.0, disturbance.position_noise, (noisy.shape[0], 2))
    return noisy
