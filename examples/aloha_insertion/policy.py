"""A scripted bimanual policy for gym-aloha's insertion task (two ViperX 300 S arms, joint position actions).

The left arm picks up the blue socket, the right arm the red peg; both lift them and bring them
together over the middle of the table, the peg's end toward the socket's opening. An action of
``gym_aloha/AlohaInsertion-v0`` is 14 absolute targets: six joint angles and a normalised gripper
opening (1 open, 0 closed) per arm, in that order for the left arm and then the right arm.

Every control step (50 per second) the policy sets a Cartesian target for each arm's pinch point
(the midpoint between its two finger pads), with the gripper pointing down at ``PITCH`` toward
the middle of the table and its fingers closing across the y axis, and solves each arm's inverse
kinematics by damped least squares on a scratch ``MjData`` of the environment's model, started
from the previous step's solution. The environment's state is only read.

Phases, in control steps (the episode lasts :data:`STEPS` steps, 3 s):

1. ``approach`` (0-40): over the grasp point, 6 cm above it, gripper open;
2. ``descend`` (40-65): down to the grasp point;
3. ``close`` (65-80): close the gripper;
4. ``lift`` (80-125): lift to the meeting height and move toward the middle;
5. ``insert`` (125-150): move the peg's end and the socket's opening toward each other.

Noise makes some episodes fail: each arm's grasp point is offset once per episode (``grasp_noise``
m in x and y, drawn from ``rng``), and every joint target gets Gaussian noise (``joint_noise``
rad).
"""

from __future__ import annotations

import mujoco
import numpy as np

#: Control steps of one episode (3 s at 50 steps per second).
STEPS = 150
#: (name, first step) of each phase.
PHASES = (("approach", 0), ("descend", 40), ("close", 65), ("lift", 80), ("insert", 125))
#: How far the gripper's pointing direction dips below the horizontal, rad.
PITCH = np.deg2rad(50.0)
#: Height of the pinch point above an object's centre before the descent, m.
ABOVE = 0.06
#: Height the objects are lifted to, m.
MEET_HEIGHT = 0.22
ARMS = ("left", "right")
#: Which object each arm picks.
OBJECT = {"left": "socket", "right": "peg"}
#: Each arm's six joints, after its ``vx300s_left/`` or ``vx300s_right/`` prefix.
JOINT_NAMES = ("waist", "shoulder", "elbow", "forearm_roll", "wrist_angle", "wrist_rotate")


def pinch_geoms(model: mujoco.MjModel, arm: str) -> tuple[int, int]:
    """The two finger pad geoms of ``arm``."""
    return (
        model.geom(f"vx300s_{arm}/10_left_gripper_finger").id,
        model.geom(f"vx300s_{arm}/10_right_gripper_finger").id,
    )


class ScriptedInsertion:
    """Pick both objects up and bring them together (see the module docstring).

    Args:
        model: the environment's compiled model (``physics.model.ptr``).
        rng: random generator of the noise.
        grasp_noise: standard deviation of each grasp point's offset in x and y, m.
        joint_noise: standard deviation of the noise on every joint target, rad.

    """

    def __init__(
        self,
        model: mujoco.MjModel,
        rng: np.random.Generator,
        *,
        grasp_noise: float = 0.012,
        joint_noise: float = 0.01,
    ) -> None:
        self.model = model
        self.scratch = mujoco.MjData(model)
        self.rng = rng
        self.joint_noise = joint_noise
        self.step = 0
        self.offsets = {arm: np.append(rng.normal(0.0, grasp_noise, size=2), 0.0) for arm in ARMS}
        self.joints = {arm: [model.joint(f"vx300s_{arm}/{name}").id for name in JOINT_NAMES] for arm in ARMS}
        self.qpos = {arm: np.array([model.jnt_qposadr[j] for j in self.joints[arm]]) for arm in ARMS}
        self.dofs = {arm: np.array([model.jnt_dofadr[j] for j in self.joints[arm]]) for arm in ARMS}
        self.gripper = {arm: model.body(f"vx300s_{arm}/gripper_link").id for arm in ARMS}
        self.pads = {arm: pinch_geoms(model, arm) for arm in ARMS}
        self.solution: dict[str, np.ndarray] = {}
        self.grasp: dict[str, np.ndarray] = {}
        self.start: dict[str, np.ndarray] = {}

    @property
    def phase(self) -> str:
        """The current phase's name."""
        return [name for name, first in PHASES if self.step >= first][-1]

    def _direction(self, arm: str) -> np.ndarray:
        """The gripper's pointing direction: toward the middle of the table, dipped by :data:`PITCH`."""
        sign = 1.0 if arm == "left" else -1.0
        return np.array([sign * np.cos(PITCH), 0.0, -np.sin(PITCH)])

    def _targets(self, data: mujoco.MjData) -> tuple[dict[str, np.ndarray], float]:
        """Each arm's pinch point target and the gripper opening for this step."""
        phase = self.phase
        if not self.grasp:
            for arm in ARMS:
                centre = np.array(data.xpos[self.model.body(OBJECT[arm]).id])
                # The peg is taken 3 cm from its outer end, the socket 3 cm from its outer edge.
                outward = -1.0 if arm == "left" else 1.0
                self.grasp[arm] = centre + np.array([outward * 0.03, 0.0, 0.0]) + self.offsets[arm]
        fraction = {
            "approach": min(1.0, self.step / 30),
            "descend": min(1.0, (self.step - 40) / 20),
            "lift": min(1.0, (self.step - 80) / 35),
            "insert": min(1.0, (self.step - 125) / 20),
        }.get(phase, 1.0)
        targets = {}
        for arm in ARMS:
            sign = -1.0 if arm == "left" else 1.0
            grasp = self.grasp[arm]
            above = grasp + np.array([0.0, 0.0, ABOVE])
            meet = np.array([sign * 0.12, 0.5, MEET_HEIGHT])
            inserted = np.array([sign * 0.07, 0.5, MEET_HEIGHT])
            if phase == "approach":
                start = self.start.setdefault(arm, self._pinch(data, arm))
                targets[arm] = start + fraction * (above - start)
            elif phase == "descend":
                targets[arm] = above + fraction * (grasp - above)
            elif phase == "close":
                targets[arm] = grasp
            elif phase == "lift":
                targets[arm] = grasp + fraction * (meet - grasp)
            else:
                targets[arm] = meet + fraction * (inserted - meet)
        opening = 1.0 if phase in ("approach", "descend") else 0.0
        return targets, opening

    def _pinch(self, data: mujoco.MjData, arm: str) -> np.ndarray:
        first, second = self.pads[arm]
        return 0.5 * (np.array(data.geom_xpos[first]) + np.array(data.geom_xpos[second]))

    def _solve(self, arm: str, start: np.ndarray, target: np.ndarray, iterations: int) -> np.ndarray:
        """Joint angles (6,) that put ``arm``'s pinch point at ``target``, pointing along its direction."""
        model, scratch = self.model, self.scratch
        qpos, dofs = self.qpos[arm], self.dofs[arm]
        scratch.qpos[qpos] = start
        direction = self._direction(arm)
        jacobian_p = np.zeros((3, model.nv))
        jacobian_r = np.zeros((3, model.nv))
        low, high = model.jnt_range[self.joints[arm], 0], model.jnt_range[self.joints[arm], 1]
        for _ in range(iterations):
            mujoco.mj_kinematics(model, scratch)
            frame = scratch.xmat[self.gripper[arm]].reshape(3, 3)
            pinch = self._pinch(scratch, arm)
            # x axis along the direction, y axis (the fingers' closing axis) horizontal.
            rotation_error = np.cross(frame[:, 0], direction) + 0.5 * np.cross(frame[:, 1], [0.0, frame[1, 1], 0.0])
            error = np.concatenate([target - pinch, 0.3 * rotation_error])
            mujoco.mj_comPos(model, scratch)
            mujoco.mj_jac(model, scratch, jacobian_p, jacobian_r, pinch, self.gripper[arm])
            jacobian = np.vstack([jacobian_p[:, dofs], 0.3 * jacobian_r[:, dofs]])
            step = jacobian.T @ np.linalg.solve(jacobian @ jacobian.T + 1e-4 * np.eye(6), error)
            scratch.qpos[qpos] = np.clip(scratch.qpos[qpos] + step, low, high)
        return np.array(scratch.qpos[qpos])

    def __call__(self, data: mujoco.MjData) -> np.ndarray:
        """The action (14,) for the state in ``data``."""
        targets, opening = self._targets(data)
        action = np.zeros(14)
        for index, arm in enumerate(ARMS):
            start = self.solution.get(arm, np.array(data.qpos[self.qpos[arm]]))
            self.solution[arm] = self._solve(arm, start, targets[arm], 30 if arm not in self.solution else 8)
            joints = self.solution[arm] + self.rng.normal(0.0, self.joint_noise, size=6)
            action[7 * index : 7 * index + 6] = joints
            action[7 * index + 6] = opening
        self.step += 1
        return action
