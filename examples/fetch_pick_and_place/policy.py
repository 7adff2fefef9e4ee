"""A scripted pick-and-place policy for gymnasium-robotics' FetchPickAndPlace-v4, and a fixed goal.

FetchPickAndPlace's action is a displacement of the gripper's mocap body (1 = 5 cm per step of
0.04 s) and a finger command (-1 closes, +1 opens). The policy reads only the observation:

1. ``above``: the gripper (site ``robot0:grip``) goes 8 cm above the block, fingers open;
2. ``down``: it comes down to the block's centre;
3. ``close``: it closes the fingers until they are less than 5.5 cm apart (open: 10 cm);
4. ``carry``: fingers closed, it carries the block to the goal.

Each phase moves toward its target with a proportional command (10 per metre, clipped to [-1, 1]).
Gaussian noise of standard deviation ``noise`` on all four action components makes some episodes
fail: the gripper misses the block, closes beside it, or loses it on the way.

The environment draws a new goal at every reset (half of them in the air). A scene file holds one
success set, so :class:`FixedGoal` puts the goal where :data:`GOAL` says after every reset, with the
environment's own ``_render_callback`` moving the goal marker (site ``target0``) there, and returns
the observation of that goal. The block's start stays the environment's random one.
"""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np

#: The goal of every episode (world frame, m): 13 cm above the table top, inside the environment's
#: own goal range (x 1.19-1.49, y 0.60-0.90, z 0.42-0.87).
GOAL = np.array([1.30, 0.85, 0.55])
#: The environment's success radius (``distance_threshold``), m.
SUCCESS_RADIUS = 0.05
#: Phases of the policy, in order.
PHASES = ("above", "down", "close", "carry")


class FixedGoal(gymnasium.Wrapper):
    """Every episode's goal is ``goal``; the goal marker ``target0`` is moved there at reset."""

    def __init__(self, env: gymnasium.Env, goal: np.ndarray = GOAL) -> None:
        super().__init__(env)
        self.goal = np.asarray(goal, dtype=float)

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        """The environment's reset, then the fixed goal (its observation and its marker)."""
        _, info = self.env.reset(**kwargs)
        inner = self.env.unwrapped
        inner.goal = self.goal.copy()
        inner._render_callback()  # the environment's own code: site target0 at the goal
        return inner._get_obs(), info


class ScriptedPickAndPlace:
    """Above the block, down, close, carry to the goal (see the module docstring).

    Args:
        noise: standard deviation of the Gaussian action noise.
        rng: random generator of the noise.
        gain: proportional gain, 1/m.
        hover: height above the block of the first target, m.
        closed: finger opening (sum of both finger joints, m) at which the grasp counts as closed.

    """

    def __init__(
        self,
        noise: float,
        rng: np.random.Generator,
        *,
        gain: float = 10.0,
        hover: float = 0.08,
        closed: float = 0.055,
    ) -> None:
        self.noise = noise
        self.rng = rng
        self.gain = gain
        self.hover = hover
        self.closed = closed
        self.phase = PHASES[0]

    def reset(self) -> None:
        """A new episode starts above the block."""
        self.phase = PHASES[0]

    def __call__(self, observation: dict[str, np.ndarray]) -> np.ndarray:
        """The next action, in [-1, 1]^4."""
        state = observation["observation"]
        grip, block = state[:3], state[3:6]
        goal = observation["desired_goal"]
        opening = float(state[9] + state[10])
        above = block + np.array([0.0, 0.0, self.hover])
        if self.phase == "above" and np.linalg.norm(above - grip) < 0.015:
            self.phase = "down"
        if self.phase == "down" and np.linalg.norm(block - grip) < 0.01:
            self.phase = "close"
        if self.phase == "close" and opening < self.closed:
            self.phase = "carry"
        target = {
            "above": above,
            "down": block,
            "close": block,
            "carry": goal,
        }[self.phase]
        fingers = 1.0 if self.phase in ("above", "down") else -1.0
        action = np.concatenate([np.clip(self.gain * (target - grip), -1.0, 1.0), [fingers]])
        action += self.noise * self.rng.normal(size=4)
        return np.clip(action, -1.0, 1.0).astype(np.float32)
