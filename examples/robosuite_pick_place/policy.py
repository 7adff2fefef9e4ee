"""A scripted pick-and-place policy for robosuite's PickPlace task (Panda arm, OSC_POSE controller).

The policy picks one of the four objects (milk, bread, cereal, can) from ``bin1`` and carries it
over ``bin2``, where it opens the gripper. It commands robosuite's default Panda controller,
``OSC_POSE`` with delta inputs: an action is ``(dx, dy, dz, rx, ry, rz, gripper)`` in [-1, 1],
where 1 moves the end effector 5 cm (``output_max``) and the gripper closes at +1 and opens at -1.

Phases (20 control steps per second):

1. ``above``: over the chosen object, 12 cm above its centre (at most 60 steps);
2. ``descend``: down to the object's centre (at most 40 steps);
3. ``close``: close the gripper (10 steps);
4. ``lift``: up to 1.05 m (15 steps);
5. ``carry``: over ``bin2``'s centre plus a drawn offset (at most 60 steps);
6. ``release``: open the gripper, then hold.

Noise makes some episodes fail: the grasp point is drawn once per episode around the object's
centre (``grasp_noise`` m in x and y), and every action gets Gaussian noise (``action_noise``).
The policy reads only the environment's state (``sim.data``); it keeps its own step counters.
"""

from __future__ import annotations

from typing import Any

import numpy as np

OBJECTS = ("Milk", "Bread", "Cereal", "Can")
#: The gripper's grasp site in robosuite 1.5's Panda gripper.
GRIP_SITE = "gripper0_right_grip_site"
#: Height the object is lifted to and carried at, m (bin tops are at about 0.85 m).
CARRY_HEIGHT = 1.05
#: The OSC_POSE controller's largest position step per action unit, m.
OUTPUT_MAX = 0.05
#: (phase, most steps) in order; ``release`` lasts until the episode ends.
PHASES = (("above", 60), ("descend", 40), ("close", 10), ("lift", 15), ("carry", 60), ("release", 10**9))


class ScriptedPickPlace:
    """Pick one object out of ``bin1`` and drop it over ``bin2`` (see the module docstring).

    Args:
        env: the robosuite environment (``env.sim`` is read, never written).
        rng: random generator of the object choice and the noise.
        action_noise: standard deviation of the noise added to every action component.
        grasp_noise: standard deviation of the grasp point's offset from the object's centre, m.
        target: the object to pick (one of :data:`OBJECTS`); ``None`` draws one.

    """

    def __init__(
        self,
        env: Any,
        rng: np.random.Generator,
        *,
        action_noise: float = 0.1,
        grasp_noise: float = 0.015,
        target: str | None = None,
    ) -> None:
        self.env = env
        self.rng = rng
        self.action_noise = action_noise
        self.target = target if target is not None else str(rng.choice(OBJECTS))
        self.grasp_offset = np.append(rng.normal(0.0, grasp_noise, size=2), 0.0)
        self.drop_offset = np.append(rng.uniform(-0.06, 0.06, size=2), 0.0)
        self.phase_index = 0
        self.phase_steps = 0

    @property
    def phase(self) -> str:
        """The current phase's name."""
        return PHASES[self.phase_index][0]

    def _positions(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        model, data = self.env.sim.model._model, self.env.sim.data._data
        grip = np.array(data.site_xpos[model.site(GRIP_SITE).id])
        target = np.array(data.xpos[model.body(f"{self.target}_main").id])
        bin2 = np.array(data.xpos[model.body("bin2").id])
        return grip, target, bin2

    def _goal(self, grip: np.ndarray, target: np.ndarray, bin2: np.ndarray) -> tuple[np.ndarray, float, bool]:
        """The end effector's goal, the gripper command and whether the phase is done."""
        phase = self.phase
        if phase == "above":
            goal = target + self.grasp_offset + np.array([0.0, 0.0, 0.12])
            return goal, -1.0, bool(np.linalg.norm(goal - grip) < 0.02)
        if phase == "descend":
            goal = target + self.grasp_offset
            return goal, -1.0, bool(np.linalg.norm(goal - grip) < 0.012)
        if phase == "close":
            return grip, 1.0, False
        if phase == "lift":
            return np.array([grip[0], grip[1], CARRY_HEIGHT]), 1.0, False
        if phase == "carry":
            goal = np.array([bin2[0], bin2[1], CARRY_HEIGHT]) + self.drop_offset
            return goal, 1.0, bool(np.linalg.norm(goal[:2] - grip[:2]) < 0.03)
        return grip, -1.0, False

    def __call__(self) -> np.ndarray:
        """The action (7,) for the environment's current state."""
        grip, target, bin2 = self._positions()
        goal, gripper, done = self._goal(grip, target, bin2)
        self.phase_steps += 1
        if done or self.phase_steps >= PHASES[self.phase_index][1]:
            self.phase_index = min(self.phase_index + 1, len(PHASES) - 1)
            self.phase_steps = 0
        action = np.zeros(7)
        action[:3] = np.clip((goal - grip) / OUTPUT_MAX, -1.0, 1.0)
        action[6] = gripper
        action[:6] += self.rng.normal(0.0, self.action_noise, size=6)
        return np.clip(action, -1.0, 1.0)
