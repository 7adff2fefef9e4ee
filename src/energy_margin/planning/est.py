"""Kinodynamic Expansive Space Tree grown under random wrench perturbations (Algorithm 1, line 2-3).

One iteration picks a node by inverse density, samples a duration and one wrench per object,
restores the node's simulator state, propagates the physics and, if the reached state lies in the
task's state box, adds it as a child whose cost is the parent's plus the incremental cost Q. A
rejected child still consumes the iteration. The budget is a number of iterations, a number of
nodes (children of the root), or both (whichever is reached first).

The loop itself is shared with the Monte Carlo and RRT baselines (:mod:`energy_margin.planning.tree`,
:mod:`energy_margin.planning.methods`); ``grow_tree`` selects the method by name.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from energy_margin.planning.costs import CostModel
from energy_margin.planning.density import Features
from energy_margin.planning.lockstep import grow_together
from energy_margin.planning.methods import expansion_factory
from energy_margin.planning.tree import CostField, Expansion, TreeBudget, grow
from energy_margin.sim.base import Simulator, release_states
from energy_margin.tasks.base import Task
from energy_margin.world.state import FrameState

__all__ = ["CostField", "TreeBudget", "grow_tree", "grow_trees_together"]


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
    method: str = "est",
    batch: int = 1,
    threads: int = 1,
    rollout_length: int = 10,
    rrt_extent: float = 0.1,
    stop: Callable[[CostField], bool] | None = None,
    check_every: int = 25,
    wrench_scale: float = 1.0,
    duration_scale: float = 1.0,
) -> CostField:
    """Grow a tree (EST by default) from ``root`` and return its energy-cost field.

    Args:
        simulator: a simulator built from the frame's scene.
        task: the task (wrench ranges, state box, nominal end-effector force).
        root: the frame state z_init.
        drive: the trajectory's drive parameters, shape (n_drive,).
        rng: the analysis' random generator (consumed in a fixed order).
        budget: expansions and/or nodes.
        cost_model: incremental cost Q.
        features: density features; every object's position by default.
        n_projections: number of density projections.
        cell_size: density grid cell, feature units (m).
        start_time: time of the frame within its roll-out, s (the end-effector's script clock).
        method: ``"est"``, ``"montecarlo"`` or ``"rrt"`` (:mod:`energy_margin.planning.methods`).
        batch: expansions propagated together through ``mujoco.rollout`` (1: one at a time).
        threads: ``mujoco.rollout`` threads when ``batch`` > 1.
        rollout_length: Monte Carlo propagations per roll-out.
        rrt_extent: RRT target box half width, m.
        stop: early-stopping rule called every ``check_every`` expansions (see
            :func:`~energy_margin.planning.tree.grow`).
        check_every: expansions between two calls of ``stop``.
        wrench_scale: factor on the task's perturbation wrench bounds.
        duration_scale: factor on the task's longest perturbation propagation.

    The end-effector keeps following its script: its command (:func:`command_robot`, without
    random variation) is evaluated at ``start_time`` plus the node's time when a propagation
    starts, and again every :attr:`Task.control_period` seconds within it when the task sets one.
    """
    make = _expansion(method, root, budget, n_projections, cell_size, rollout_length, rrt_extent)
    try:
        return grow(
            simulator,
            task,
            root,
            drive,
            rng,
            make,
            budget=budget,
            cost_model=cost_model,
            features=features,
            start_time=start_time,
            batch=batch,
            threads=threads,
            stop=stop,
            check_every=check_every,
            wrench_scale=wrench_scale,
            duration_scale=duration_scale,
        )
    finally:
        # Engines that keep saved states outside the node array (PyBullet) free them now.
        release_states(simulator)


def grow_trees_together(
    simulators: Sequence[Simulator],
    task: Task,
    roots: Sequence[FrameState],
    drives: Sequence[np.ndarray],
    rngs: Sequence[np.random.Generator],
    *,
    budget: TreeBudget,
    cost_model: CostModel,
    start_times: Sequence[float],
    batch: int,
    features: Features | None = None,
    n_projections: int = 8,
    cell_size: float = 0.01,
    method: str = "est",
    rollout_length: int = 10,
    rrt_extent: float = 0.1,
    stops: Sequence[Callable[[CostField], bool] | None] | None = None,
    check_every: int = 25,
    wrench_scale: float = 1.0,
    duration_scale: float = 1.0,
    propagating: Simulator | None = None,
) -> list[CostField]:
    """Grow one tree per root (frames of one or more roll-outs of a scene) in lockstep, each round one batched call.

    Each tree is the tree :func:`grow_tree` grows from its root and generator with ``batch``
    (:func:`~energy_margin.planning.tree.grow_together`); the arguments are :func:`grow_tree`'s,
    one per root where they are lists.
    """
    makes = [_expansion(method, root, budget, n_projections, cell_size, rollout_length, rrt_extent) for root in roots]
    return grow_together(
        simulators,
        task,
        roots,
        drives,
        rngs,
        makes,
        budget=budget,
        cost_model=cost_model,
        start_times=start_times,
        batch=batch,
        features=features,
        stops=stops,
        check_every=check_every,
        wrench_scale=wrench_scale,
        duration_scale=duration_scale,
        propagating=propagating,
    )


def _expansion(
    method: str,
    root: FrameState,
    budget: TreeBudget,
    n_projections: int,
    cell_size: float,
    rollout_length: int,
    rrt_extent: float,
) -> Callable[[np.random.Generator, np.ndarray, Features], Expansion]:
    """The ``make_expansion`` of ``method`` for a tree of ``budget`` (:func:`grow_tree`'s arguments)."""
    total = budget.expansions if budget.expansions is not None else budget.node_capacity - 1
    return expansion_factory(
        method,
        n_objects=root.n_objects,
        total=int(total),
        capacity=budget.node_capacity,
        n_projections=n_projections,
        cell_size=cell_size,
        rollout_length=rollout_length,
        rrt_extent=rrt_extent,
    )
