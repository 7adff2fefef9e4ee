"""Kinodynamic Expansive Space Tree grown under random wrench perturbations (Algorithm 1, line 2-3).

One iteration picks a node by inverse density, samples a duration and one wrench per object,
restores the node's simulator state, propagates the physics and, if the reached state lies in the
task's state box, adds it as a child whose cost is the parent's plus the incremental cost Q. A
rejected child still consumes the iteration. The budget is a number of iterations, a number of
nodes (children of the root), or both (whichever is reached first).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from energy_margin.energy import CostModel, Propagation
from energy_margin.planning.density import Features, ObjectPositions, ProjectedGridDensity
from energy_margin.sim.base import Simulator, release_states
from energy_margin.state import FrameState
from energy_margin.tasks.base import Task, command_robot


@dataclass(frozen=True)
class TreeBudget:
    """When tree growth stops.

    Attributes:
        iterations: number of expansions (accepted or rejected), or ``None``.
        nodes: number of accepted children of the root, or ``None``.
        max_iterations: hard cap on expansions when only ``nodes`` is given.

    """

    iterations: int | None = 300
    nodes: int | None = None
    max_iterations: int = 100_000

    def __post_init__(self) -> None:
        if self.iterations is None and self.nodes is None:
            raise ValueError("give iterations, nodes or both")
        for name in ("iterations", "nodes"):
            value = getattr(self, name)
            if value is not None and (not isinstance(value, int | np.integer) or value < 0):
                raise ValueError(f"{name} must be a non-negative integer, got {value!r}")

    @property
    def iteration_limit(self) -> int:
        """Largest number of expansions."""
        return int(self.iterations) if self.iterations is not None else self.max_iterations

    @property
    def node_capacity(self) -> int:
        """Largest number of nodes including the root."""
        limit = self.iteration_limit if self.nodes is None else min(self.nodes, self.iteration_limit)
        return int(limit) + 1


@dataclass(frozen=True)
class CostField:
    """The energy-cost field {(z^m, c^m)} of one tree.

    Attributes:
        costs: cost-to-come of every node, root first, shape (M,), J.
        object_pos: object centres of every node, shape (M, n_objects, 3), m.
        object_vel: object linear then angular velocities of every node, shape (M, n_objects, 6),
            m/s and rad/s, world frame.
        parents: parent index of every node (-1 for the root), shape (M,).
        times: simulated time of every node, shape (M,), s.
        iterations: expansions performed (accepted and rejected).
        physics_s: wall time spent inside the simulator, s.
        total_s: wall time of the whole growth, s.

    """

    costs: np.ndarray
    object_pos: np.ndarray
    object_vel: np.ndarray
    parents: np.ndarray
    times: np.ndarray
    iterations: int
    physics_s: float
    total_s: float

    @property
    def nodes(self) -> int:
        """Number of nodes including the root."""
        return int(self.costs.shape[0])


def grow_tree(
    simulator: Simulator,
    task: Task,
    root: FrameState,
    drive: np.ndarray,
    rng: np.random.Generator,
    *,
    budget: TreeBudget,
    cost_model: CostModel,
    features: Features | None = None,
    n_projections: int = 8,
    cell_size: float = 0.01,
    start_time: float = 0.0,
) -> CostField:
    """Grow an EST from ``root`` and return its energy-cost field.

    Args:
        simulator: a simulator built from the frame's scene.
        task: the task (wrench ranges, state box, nominal end-effector force).
        root: the frame state z_init.
        drive: the trajectory's drive parameters, shape (n_drive,).
        rng: the analysis' random generator (consumed in a fixed order).
        budget: iterations and/or nodes.
        cost_model: incremental cost Q.
        features: density features; every object's position by default.
        n_projections: number of density projections.
        cell_size: density grid cell, feature units (m).
        start_time: time of the frame within its roll-out, s (the end-effector's script clock).

    The end-effector keeps following its script: its command (:func:`command_robot`, without
    random variation) is evaluated at ``start_time`` plus the node's time when a propagation
    starts, and again every :attr:`Task.control_period` seconds within it when the task sets one.
    """
    started = time.perf_counter()
    try:
        return _grow(
            simulator,
            task,
            root,
            drive,
            rng,
            budget,
            cost_model,
            features,
            n_projections,
            cell_size,
            start_time,
            started,
        )
    finally:
        # Engines that keep saved states outside the node array (PyBullet) free them now.
        release_states(simulator)


def _grow(
    simulator: Simulator,
    task: Task,
    root: FrameState,
    drive: np.ndarray,
    rng: np.random.Generator,
    budget: TreeBudget,
    cost_model: CostModel,
    features: Features | None,
    n_projections: int,
    cell_size: float,
    start_time: float,
    started: float,
) -> CostField:
    features = features if features is not None else ObjectPositions()
    limits = task.wrench_limits(simulator.scene)
    max_wrench = limits.max_wrench
    duration_exponent = 1.0 / max(limits.control_dimension, 1)
    dt = simulator.timestep
    needs_friction = cost_model.needs_friction_work
    n_objects = root.n_objects

    simulator.reset(root)
    capacity = budget.node_capacity
    states = np.empty((capacity, simulator.state_size))
    costs = np.empty(capacity)
    parents = np.empty(capacity, dtype=np.int64)
    times = np.empty(capacity)
    positions = np.empty((capacity, n_objects, 3))
    velocities = np.empty((capacity, n_objects, 6))
    quaternions = np.empty((capacity, n_objects, 4))
    energies = np.zeros(capacity)
    states[0] = simulator.get_state()
    costs[0], parents[0], times[0] = 0.0, -1, 0.0
    positions[0] = simulator.object_positions()
    velocities[0] = simulator.object_velocities()
    quaternions[0] = simulator.object_quaternions()
    if needs_friction:
        energies[0] = simulator.mechanical_energy()
    root_pos = positions[0].copy()
    density = ProjectedGridDensity(features.dimension(n_objects), rng, n_projections=n_projections, cell_size=cell_size)
    picks = np.empty((0, 3))
    unit_wrenches = np.empty((0, *max_wrench.shape))
    all_steps = np.empty(0, dtype=np.int64)
    density.add(0, features(positions[0], root_pos))

    count = 1
    iterations = 0
    physics_s = 0.0
    iteration_limit = budget.iteration_limit
    control_steps = max(1, round(task.control_period / dt)) if task.control_period is not None else None
    # Random numbers are drawn in blocks (fewer generator calls); the stream stays a fixed function
    # of the seed.
    block = 256
    while iterations < iteration_limit and count < capacity:
        slot = iterations % block
        if slot == 0:
            size = min(block, iteration_limit - iterations)
            picks = rng.random((size, 3))
            unit_wrenches = rng.uniform(-1.0, 1.0, (size, *max_wrench.shape))
            all_steps = np.maximum(
                1, (limits.max_duration * rng.random(size) ** duration_exponent / dt).astype(np.int64)
            )
        iterations += 1
        parent = density.select(picks[slot])
        wrenches = unit_wrenches[slot] * max_wrench
        n_steps = int(all_steps[slot])

        tick = time.perf_counter()
        simulator.set_state(states[parent])
        simulator.set_object_wrenches(wrenches)
        friction_work = 0.0
        done = 0
        while done < n_steps:
            chunk = n_steps - done if control_steps is None else min(control_steps, n_steps - done)
            command_robot(task, simulator, drive, start_time + times[parent] + done * dt, None)
            friction_work += simulator.step(chunk, track_friction_work=needs_friction)
            done += chunk
        pos_after = simulator.object_positions()
        vel_after = simulator.object_velocities()
        physics_s += time.perf_counter() - tick

        if not np.isfinite(pos_after.sum() + vel_after.sum()):
            continue
        if not task.within_bounds(pos_after, vel_after):
            continue
        tick = time.perf_counter()
        quat_after = simulator.object_quaternions()
        energy_after = simulator.mechanical_energy() if needs_friction else 0.0
        states[count] = simulator.get_state()
        physics_s += time.perf_counter() - tick
        increment = cost_model(
            Propagation(
                wrenches=wrenches,
                pos_before=positions[parent],
                pos_after=pos_after,
                quat_before=quaternions[parent],
                quat_after=quat_after,
                energy_before=float(energies[parent]),
                energy_after=energy_after,
                friction_work=friction_work,
            )
        )
        costs[count] = costs[parent] + increment
        parents[count] = parent
        times[count] = times[parent] + n_steps * dt
        positions[count] = pos_after
        velocities[count] = vel_after
        quaternions[count] = quat_after
        energies[count] = energy_after
        density.add(count, features(pos_after, root_pos))
        count += 1

    return CostField(
        costs=costs[:count].copy(),
        object_pos=positions[:count].copy(),
        object_vel=velocities[:count].copy(),
        parents=parents[:count].copy(),
        times=times[:count].copy(),
        iterations=iterations,
        physics_s=physics_s,
        total_s=time.perf_counter() - started,
    )
