"""A scripted pushing policy for Gymnasium's Pusher-v5: the fingertip goes behind the puck, then pushes it to the goal.

The fingertip body ``tips_arm`` carries a fork of three capsules (radius 0.02 m; the only arm
geoms that touch the puck): a 0.2 m cross bar through the body's origin and two 0.1 m prongs
along the body's x axis. The policy pushes with the cross bar, held horizontal and across the
line from the puck to the goal, prongs pointing up as far as the joint limits allow. Three
phases:

1. ``approach``: the fingertip goes to a point ``standoff`` behind the puck on the line from the
   goal through the puck, at the puck's centre height; while it is near the puck and not yet
   behind it, ``lift`` higher, so that the bar passes over the puck (whose top is 0.05 m above
   its centre);
2. ``descend``: once within 3 cm of that point, it comes down to the puck's centre height;
3. ``push``: it follows a target on the current puck-goal line that presses the bar ``press``
   into the puck and moves at most ``step`` ahead of the fingertip per step; once the puck is at
   the goal the target only touches it. When the fingertip falls off the line by more than
   ``lost``, or gets past the puck's centre, the policy goes back to ``approach``.

Pusher's puck weighs 8e-6 kg, so MuJoCo's contact regularisation makes its contacts very soft:
the force on it grows with the penetration (about 0.4 N/m), and its slide joints are damped
(0.5 N s/m). The push is therefore slow (about 3-4 cm/s with the bar 6 cm deep) and a puck far
from the goal does not get there within the episode's 5 s.

Each step solves the arm's inverse kinematics for the fingertip's target position and the bar's
orientation by damped least squares on a scratch ``MjData`` (joint limits respected), then drives
the joints there with a proportional-derivative torque clipped to the action range [-2, 2] N m;
Gaussian noise on the torques makes some episodes fail. The policy only reads the environment's
state.

A copy (``copy.deepcopy``, what the live scorer runs to continue the success score from a tree's
states) keeps the phase and the last solution, shares the model, and draws its noise from a
generator of its own, spawned from the policy's seed: the copies' noise is not the episode's.
"""

from __future__ import annotations

import copy
from typing import Any

import mujoco
import numpy as np

#: Radius of Pusher's puck (the ``object`` cylinder), m.
PUCK_RADIUS = 0.05
#: Radius of the fork's capsules, m.
CAPSULE_RADIUS = 0.02
#: The action range of every joint, N m.
TORQUE_LIMIT = 2.0


class ScriptedPusher:
    """Approach behind the puck, come down, then push it along the line to the goal (see the module docstring).

    Args:
        model: the environment's model.
        noise: standard deviation of the torque noise, N m.
        rng: random generator of the noise.
        stiffness: joint-space proportional gain, N m/rad.
        damping: joint-space derivative gain, N m s/rad.
        standoff: distance from the puck's centre to the fingertip before the descent, m.
        lift: height above the puck's centre while the fingertip passes over the puck, m.
        press: how deep the pushing target presses the bar into the puck's soft contact, m.
        step: how far the pushing target runs ahead of the fingertip, m.
        lost: distance of the fingertip from the puck-goal line that restarts the approach, m.
        upright: weight of "prongs up" in the inverse kinematics (the bar's direction weighs 0.3).

    """

    def __init__(
        self,
        model: mujoco.MjModel,
        noise: float,
        rng: np.random.Generator,
        *,
        stiffness: float = 12.0,
        damping: float = 1.2,
        standoff: float = 0.13,
        lift: float = 0.1,
        press: float = 0.065,
        step: float = 0.03,
        lost: float = 0.06,
        upright: float = 0.1,
    ) -> None:
        self.model = model
        self.scratch = mujoco.MjData(model)
        self.noise = noise
        self.rng = rng
        self.stiffness = stiffness
        self.damping = damping
        self.standoff = standoff
        self.lift = lift
        self.press = press
        self.step = step
        self.lost = lost
        self.upright = upright
        self.tip = model.body("tips_arm").id
        self.puck = model.body("object").id
        self.goal = model.body("goal").id
        self.low, self.high = model.jnt_range[:7, 0], model.jnt_range[:7, 1]
        self.limited = model.jnt_limited[:7].astype(bool)
        self.phase = "approach"
        self.solution: np.ndarray | None = None
        self.roll = 0.0

    def reset(self, rng: np.random.Generator | None = None) -> None:
        """A new episode starts with the approach (and draws its noise from ``rng`` when given)."""
        self.phase = "approach"
        self.solution = None
        if rng is not None:
            self.rng = rng

    def __deepcopy__(self, memo: dict[int, Any]) -> ScriptedPusher:
        """A copy with its own scratch data and noise (spawned from this policy's seed), the model shared."""
        other = copy.copy(self)
        other.scratch = mujoco.MjData(self.model)
        other.solution = None if self.solution is None else self.solution.copy()
        other.rng = np.random.default_rng(self.rng.bit_generator.seed_seq.spawn(1)[0])  # type: ignore[attr-defined]
        return other

    def _reference(self, target: np.ndarray, roll: float) -> np.ndarray:
        """A posture reaching down toward ``target``, the upper arm rolled by ``roll``: where the solver starts."""
        shoulder = self.model.body("r_shoulder_pan_link").pos
        pan = np.arctan2(target[1] - shoulder[1], target[0] - shoulder[0])
        return np.clip(np.array([pan, 1.1, roll, -1.6, 0.0, -1.0, 0.0]), self.low, self.high)

    def _solve(
        self, start: np.ndarray, reference: np.ndarray, target: np.ndarray, heading: np.ndarray, iterations: int
    ) -> tuple[np.ndarray, float]:
        """Damped least squares from ``start``; returns the joint positions and their weighted error."""
        model, scratch = self.model, self.scratch
        scratch.qpos[:7] = start
        bar = np.cross([0.0, 0.0, 1.0], heading)
        up = np.array([0.0, 0.0, 1.0])
        position_jacobian = np.zeros((3, model.nv))
        rotation_jacobian = np.zeros((3, model.nv))
        error = np.zeros(6)
        for iteration in range(iterations + 1):
            mujoco.mj_kinematics(model, scratch)
            frame = scratch.xmat[self.tip].reshape(3, 3)
            # The bar (the body's y axis) across the pushing direction; weaker, the prongs (x axis) up.
            rotation_error = 0.3 * np.cross(frame[:, 1], bar) + self.upright * np.cross(frame[:, 0], up)
            error = np.concatenate([target - scratch.xpos[self.tip], rotation_error])
            if iteration == iterations:
                break
            mujoco.mj_comPos(model, scratch)
            mujoco.mj_jacBody(model, scratch, position_jacobian, rotation_jacobian, self.tip)
            jacobian = np.vstack([position_jacobian[:, :7], 0.3 * rotation_jacobian[:, :7]])
            inverse = jacobian.T @ np.linalg.inv(jacobian @ jacobian.T + 1e-3 * np.eye(6))
            step = inverse @ error + 0.05 * (np.eye(7) - inverse @ jacobian) @ (reference - scratch.qpos[:7])
            q = scratch.qpos[:7] + step
            scratch.qpos[:7] = np.where(self.limited, np.clip(q, self.low, self.high), q)
        return np.array(scratch.qpos[:7]), float(np.linalg.norm(error))

    def _inverse_kinematics(self, target: np.ndarray, heading: np.ndarray, iterations: int = 30) -> np.ndarray:
        """Joint positions that put the fingertip at ``target``, the bar across ``heading`` and the prongs up.

        The first call of an episode tries three rolls of the upper arm (the arm folds differently
        for a puck near its base) and keeps the best; later calls start from the previous step's
        solution, so that successive solutions stay on one branch, with a small pull toward the
        chosen posture that keeps the redundant joints away from their limits.
        """
        if self.solution is None:
            candidates = []
            for roll in (-1.4, 0.0, 1.4):
                reference = self._reference(target, roll)
                candidates.append((*self._solve(reference, reference, target, heading, 100), roll))
            self.roll = min(candidates, key=lambda candidate: candidate[1])[2]
            self.solution = min(candidates, key=lambda candidate: candidate[1])[0]
        reference = self._reference(target, self.roll)
        self.solution, _ = self._solve(self.solution, reference, target, heading, iterations)
        return self.solution

    def target(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """The fingertip's target position and the fork's heading (unit, horizontal) for this step."""
        tip = data.xpos[self.tip]
        puck = data.xpos[self.puck]
        goal = data.xpos[self.goal]
        offset = goal[:2] - puck[:2]
        remaining = float(np.linalg.norm(offset))
        direction = offset / max(remaining, 1e-9)
        heading = np.array([direction[0], direction[1], 0.0])
        behind = puck[:2] - self.standoff * direction
        # Signed position of the fingertip along and across the puck-goal line, from the puck's centre.
        relative = tip[:2] - puck[:2]
        along = float(relative @ direction)
        across = abs(float(relative[0] * direction[1] - relative[1] * direction[0]))
        near = float(np.linalg.norm(relative)) < self.standoff + 0.07
        if self.phase == "approach" and np.linalg.norm(tip[:2] - behind) < 0.03:
            self.phase = "descend"
        elif self.phase == "descend" and tip[2] - puck[2] < 0.02:
            self.phase = "push"
        elif self.phase == "push" and (across > self.lost or along > 0.0):
            self.phase = "approach"
        if self.phase == "approach":
            # Over the puck while near it and not yet behind it; at the puck's height elsewhere.
            over = near and along > -(PUCK_RADIUS + CAPSULE_RADIUS + 0.02)
            return np.array([behind[0], behind[1], puck[2] + (self.lift if over else 0.0)]), heading
        if self.phase == "descend":
            return np.array([behind[0], behind[1], puck[2]]), heading
        contact = PUCK_RADIUS + CAPSULE_RADIUS
        # Pressed into the puck (less near the goal), at most ``step`` ahead of the fingertip so that
        # the fingertip does not run through the slowly moving puck.
        xy = puck[:2] + min(along + self.step, min(self.press, remaining) - contact) * direction
        return np.array([xy[0], xy[1], puck[2]]), heading

    def __call__(self, data: mujoco.MjData) -> np.ndarray:
        """Torques (7,) for the state in ``data``."""
        position, heading = self.target(data)
        joints = self._inverse_kinematics(position, heading)
        torque = self.stiffness * (joints - data.qpos[:7]) - self.damping * data.qvel[:7]
        torque += self.rng.normal(0.0, self.noise, size=7)
        return np.clip(torque, -TORQUE_LIMIT, TORQUE_LIMIT)
