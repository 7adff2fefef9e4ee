"""A user's policy as the controller of a live score's success continuation.

A live state holds no recording and no declared motion: the tree grows with the robot holding its
last command, so a success region the robot reaches only by acting on (a puck pushed to a goal a
few seconds away) holds no tree state and the success score stays near 0. Given the policy that
drives the robot, the score is continued under it instead: nodes of the tree are drawn by
likelihood weight and, from each, the policy is run on the scorer's copy of the model to the
end of the episode (or a horizon), and the success score is the fraction of draws that end in
the success region (:func:`~energy_margin.analysis.continuation.controlled_success`).

The policy is a callable ``policy(data) -> ctrl`` that reads a ``mujoco.MjData`` of the user's
model (qpos, qvel, xpos, ...: the same indices as the environment's) and returns the actuator
controls, shape (nu,). Each continuation runs a deep copy of it (``copy.deepcopy``), so a policy
that keeps state (a phase, a warm start, a random generator) starts every continuation from the
state it has at the scored step and the policy driving the environment is untouched; a policy
that keeps none may return itself from ``__deepcopy__``. A copied random generator draws the
numbers the original would draw next: give the copy a generator of its own in ``__deepcopy__``
when its noise should not be the episode's own.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from energy_margin.analysis.continuation import Controller
from energy_margin.errors import EnergyMarginError
from energy_margin.sim.base import Simulator

__all__ = ["Policy", "PolicyControllers"]

#: A robot's policy: the actuator controls, shape (nu,), for the state in a ``mujoco.MjData``.
Policy = Callable[[mujoco.MjData], Any]


@dataclass(frozen=True)
class PolicyControllers:
    """Makes one continuation's controller: a deep copy of ``policy`` driving the scorer's model.

    A tree's states keep the time since the scored state; the controller puts the environment's
    clock back (``data.time`` + ``start_time``) before the policy's first call, so a policy that
    reads the time reads the episode's.

    Attributes:
        policy: the user's policy (see the module docstring).
        model: the scorer's compiled model (the simulator's), whose ``nu`` the controls must match.
        start_time: the scored state's time on the environment's clock, s.

    """

    policy: Policy
    model: mujoco.MjModel
    start_time: float = 0.0

    @classmethod
    def of(cls, policy: Policy, model: mujoco.MjModel) -> PolicyControllers:
        """Checked: ``policy`` must be callable."""
        if not callable(policy):
            raise EnergyMarginError(f"policy must be callable as policy(data) -> ctrl, got {type(policy).__name__}")
        return cls(policy, model)

    def __call__(self) -> Controller:
        """A controller running a fresh copy of the policy (clock and kinematics set right at its first call)."""
        policy, model, start_time = copy.deepcopy(self.policy), self.model, self.start_time
        first = True

        def control(simulator: Simulator) -> None:
            nonlocal first
            data: mujoco.MjData = simulator.data  # type: ignore[attr-defined]
            if first:  # a restored node state: the episode's clock, and its positions (not the last node's) in xpos
                data.time += start_time
                mujoco.mj_forward(model, data)
                first = False
            ctrl = np.asarray(policy(data), dtype=float)
            if ctrl.shape != (model.nu,):
                raise EnergyMarginError(
                    f"the policy returned controls of shape {ctrl.shape}; the model has {model.nu} actuators"
                )
            data.ctrl[:] = ctrl

        return control
