"""Holding a task's scripted command on a simulator's end-effector: :func:`command_robot`.

The data generator calls it at every step of a roll-out (with the roll-out's random generator),
the analyzer during every propagation (without): both apply the same command.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from energy_margin.sim.base import Simulator
from energy_margin.world.state import RobotState

if TYPE_CHECKING:
    from energy_margin.tasks.protocols import ScriptedMotion

__all__ = ["command_robot", "control_steps"]


def control_steps(control_period: float | None, dt: float) -> int | None:
    """Time steps of ``dt`` (s) a command is held in analysis: the control period rounded, at least one.

    ``None`` (one command a propagation) for a task without a control period.
    """
    return max(1, round(control_period / dt)) if control_period is not None else None


def command_robot(
    task: ScriptedMotion, simulator: Simulator, drive: np.ndarray, time: float, rng: np.random.Generator | None
) -> None:
    """Hold the task's scripted command at ``time`` (s) on the simulator's end-effector.

    Sets the generalized forces of :meth:`Task.robot_force`, then, for a task with servos, the
    targets of :meth:`Task.robot_targets`; both see the same :class:`RobotState` (the current
    joint positions and velocities). A task on a user's model then sets its :meth:`Task.model_command`.
    Used identically by the data generator (every step, with ``rng``) and the analyzer (with
    ``None``).
    """
    state = RobotState(drive, time, simulator.robot_positions(), simulator.robot_velocities())
    simulator.set_robot_force(task.robot_force(state, rng))
    targets = task.robot_targets(state, rng)
    if targets is not None:
        simulator.set_robot_targets(targets)
    command = task.model_command(drive, time)
    if command is not None:
        command.apply_to(simulator, purpose=task.label)
