"""Propagation of a tree's expansions: restore a node, hold random wrenches, step, read.

One expansion at a time through the simulator (:func:`_propagate_one`, which also integrates the
friction work when the cost model needs it), or a round of them together through a batched
propagator (:func:`_propagate_round`, ``mujoco.rollout``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from energy_margin.planning.nodes import Outcome, _Tree
from energy_margin.sim.base import Propagator, Simulator
from energy_margin.tasks.base import Task, command_robot

__all__: list[str] = []

#: One expansion of a round: (iteration, parent node, wrench (6,), propagation steps).
_Expansion = tuple[int, int, np.ndarray, int]


def _read(simulator: Simulator, *, needs_energy: bool) -> Outcome:
    """What the simulator holds now (the energy only when ``needs_energy``; no friction work yet)."""
    return Outcome(
        pos=simulator.object_positions().copy(),
        vel=simulator.object_velocities(),
        quat=simulator.object_quaternions().copy(),
        energy=simulator.mechanical_energy() if needs_energy else 0.0,
        friction_work=0.0,
        state=simulator.get_state(),
        robot=simulator.robot_positions(),
    )


def _propagate_round(
    propagator: Propagator,
    task: Task,
    drive: np.ndarray,
    tree: _Tree,
    round_: list[_Expansion],
    start_time: float,
    control_steps: int | None,
) -> list[Outcome]:
    """The outcomes of a round's expansions, propagated together (``mujoco.rollout``)."""
    states = tree.states[[parent for _, parent, _, _ in round_]]
    times = np.array([start_time + tree.times[parent] for _, parent, _, _ in round_])
    return _propagate_rows(propagator, task, drive, states, times, round_, control_steps)


def _propagate_rows(
    propagator: Propagator,
    task: Task,
    drive: np.ndarray,
    states: np.ndarray,
    start_times: np.ndarray,
    expansions: list[_Expansion],
    control_steps: int | None,
    models: list[Any] | None = None,
) -> list[Outcome]:
    """The outcomes of expansions from their parents' states (k, state_size) at script times (k,), s.

    ``drive``: the roll-out's (n_drive,) or each expansion's (k, n_drive); ``models``: each
    expansion's model when they come from several roll-outs (``None``: the propagator's).
    """
    pos, vel, quat, ends = propagator.propagate(
        task,
        drive,
        states,
        start_times,
        np.stack([wrenches for _, _, wrenches, _ in expansions]),
        np.array([n_steps for _, _, _, n_steps in expansions]),
        control_steps,
        models,
    )
    robots = propagator.end_robot_positions(ends)  # joint coordinates, then a model's mocap poses
    return [Outcome(pos[j], vel[j], quat[j], 0.0, 0.0, ends[j], robots[j]) for j in range(len(expansions))]


def _propagate_one(
    simulator: Simulator,
    task: Task,
    drive: np.ndarray,
    tree: _Tree,
    parent: int,
    wrenches: np.ndarray,
    n_steps: int,
    start_time: float,
    control_steps: int | None,
    needs_friction: bool,
) -> Outcome:
    """Restore ``parent``, hold the wrenches and the scripted command, step ``n_steps`` times."""
    dt = simulator.timestep
    simulator.set_state(tree.states[parent])
    simulator.set_object_wrenches(wrenches)
    friction_work = 0.0
    done = 0
    while done < n_steps:
        chunk = n_steps - done if control_steps is None else min(control_steps, n_steps - done)
        command_robot(task, simulator, drive, start_time + tree.times[parent] + done * dt, None)
        friction_work += simulator.step(chunk, track_friction_work=needs_friction)
        done += chunk
    outcome = _read(simulator, needs_energy=needs_friction)
    outcome.friction_work = friction_work
    return outcome
