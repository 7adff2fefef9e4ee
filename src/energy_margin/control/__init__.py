"""Decide with the margin: closed-loop control of a task's robot, with margins in the cost.

:mod:`~energy_margin.control.commands` says what a task's robot is commanded,
:mod:`~energy_margin.control.disturbances` what its controller's model does not know,
:mod:`~energy_margin.control.costs` what the controller minimises, :mod:`~energy_margin.control.mppi`
the controller, and :mod:`~energy_margin.control.episodes` runs episodes and writes them as a dataset.
"""

from energy_margin.control.commands import CommandSpace, command_space, register_command_space
from energy_margin.control.costs import COSTS, CostWeights
from energy_margin.control.disturbances import DISTURBANCES, Disturbance
from energy_margin.control.episode_scores import ControlResult
from energy_margin.control.episodes import POLICIES, run_control, run_episode
from energy_margin.control.mppi import Controller, ControllerConfig

__all__ = [
    "COSTS",
    "DISTURBANCES",
    "POLICIES",
    "CommandSpace",
    "ControlResult",
    "Controller",
    "ControllerConfig",
    "CostWeights",
    "Disturbance",
    "command_space",
    "register_command_space",
    "run_control",
    "run_episode",
]
