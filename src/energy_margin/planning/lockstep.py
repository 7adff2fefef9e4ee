"""Trees grown in lockstep: each round of every tree still growing is one batched call.

A device engine (``mujoco-warp``) steps thousands of worlds at once; one tree's round of
expansions fills a few dozen. :func:`grow_together` grows many trees, of the frames of one or more
roll-outs of a scene, side by side with the loop of :func:`~energy_margin.planning.tree.grow`:
every tree picks its parents and controls as it would alone, one call propagates all of them, and
each tree takes its own outcomes back. A propagation depends on nothing but its own inputs, so
every tree is the tree :func:`~energy_margin.planning.tree.grow` grows alone with the same seed
and ``batch``, bit for bit (tested on ``mujoco.rollout`` and on MuJoCo Warp's CPU device).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from energy_margin.errors import InvalidParameterError, check_positive_int
from energy_margin.planning.costs import CostModel
from energy_margin.planning.density import Features, ObjectPositions
from energy_margin.planning.nodes import CostField
from energy_margin.planning.propagate import _Expansion, _propagate_rows
from energy_margin.planning.tree import Expansion, TreeBudget, _batch_propagator, _Bounds, _Growth
from energy_margin.sim.base import CompiledModel, Propagator, Simulator, require
from energy_margin.tasks.base import Task
from energy_margin.world.state import FrameState

__all__ = ["grow_together"]


def grow_together(
    simulators: Sequence[Simulator],
    task: Task,
    roots: Sequence[FrameState],
    drives: Sequence[np.ndarray],
    rngs: Sequence[np.random.Generator],
    make_expansions: Sequence[Callable[[np.random.Generator, np.ndarray, Features], Expansion]],
    *,
    budget: TreeBudget,
    cost_model: CostModel,
    start_times: Sequence[float],
    batch: int,
    features: Features | None = None,
    stops: Sequence[Callable[[CostField], bool] | None] | None = None,
    check_every: int = 25,
    wrench_scale: float = 1.0,
    duration_scale: float = 1.0,
    propagating: Simulator | None = None,
) -> list[CostField]:
    """Grow one tree per root in lockstep: each round of every tree still growing is one batched call.

    Every tree is the one :func:`grow` grows alone from the same arguments with ``batch``; only the
    wall time changes. The roots may come from several roll-outs of one scene: every call
    propagates each row on its root's model (its friction, its masses) with its drive.

    Args:
        simulators: each root's simulator, of one scene (the first one's batched propagator runs
            every call); the same simulator may serve several roots.
        task: the task.
        roots: the frame states, one tree each.
        drives: each root's drive parameters, shape (n_drive,).
        rngs: one generator per root.
        make_expansions: one method factory per root (as :func:`grow`'s ``make_expansion``).
        budget: expansions and/or nodes, per tree.
        cost_model: incremental cost Q (``"wrench"``: batched propagation).
        start_times: each root's time within its roll-out, s.
        batch: expansions per tree per round, >= 2.
        features: density features (every object's displacement from the root by default).
        stops: an early-stopping rule per tree (or ``None``), as :func:`grow`'s ``stop``.
        check_every: expansions between two calls of a tree's ``stop``.
        wrench_scale: factor on the task's perturbation wrench bounds.
        duration_scale: factor on the task's longest perturbation propagation.
        propagating: the simulator whose batched propagator runs every call, of the same scene
            (the first root's when ``None``), to reuse one device copy across groups.

    Returns:
        The cost field of each root's tree. Its ``physics_s`` is the tree's share (by propagations)
        of the batched calls' wall time, its ``total_s`` the group's wall time over the trees.

    Raises:
        InvalidParameterError: mismatched lists, ``batch`` < 2, or a simulator without batched
            propagation.
        IncompatibleModelsError: roots' models the propagator cannot run in one call (they differ
            in more than it batches per world), raised before anything is grown.

    """
    started = time.perf_counter()
    n = len(roots)
    _check_lists(n, (simulators, drives, rngs, make_expansions, start_times), stops, batch, check_every)
    features = features if features is not None else ObjectPositions()
    lead = propagating if propagating is not None else simulators[0]
    propagator = _batch_propagator(lead, cost_model, batch, 1)
    assert propagator is not None
    growths = []
    for j in range(n):
        bounds = _Bounds.of(simulators[j], task, cost_model, wrench_scale, duration_scale)
        growth = _Growth.plant(simulators[j], task, roots[j], drives[j], rngs[j], make_expansions[j], budget,
                               cost_model, features, propagator, bounds)  # fmt: skip
        growth.start(budget, stops[j] if stops is not None else None, check_every)
        growths.append(growth)
    models = _row_models(simulators, lead, propagator)
    physics = _grow_rounds(propagator, task, growths, drives, start_times, models, batch)
    elapsed = time.perf_counter() - started
    # Each tree's total_s is the group's wall time over the trees (``field`` measures from its ``started``).
    return [
        growth.tree.field(growth.expansions, float(physics[j]), time.perf_counter() - elapsed / n)
        for j, growth in enumerate(growths)
    ]


def _grow_rounds(
    propagator: Propagator,
    task: Task,
    growths: list[_Growth],
    drives: Sequence[np.ndarray],
    start_times: Sequence[float],
    models: list[Any] | None,
    batch: int,
) -> np.ndarray:
    """Round after round, every tree still growing propagated in one call: each tree's physics seconds, shape (n,)."""
    physics = np.zeros(len(growths))
    while rounds := [
        (j, round_) for j, growth in enumerate(growths) if (round_ := growth.next_round(batch)) is not None
    ]:
        physics += _propagate_together(propagator, task, growths, rounds, drives, start_times, models)
    return physics


def _check_lists(
    n: int, lists: tuple[Sequence[object], ...], stops: Sequence[object] | None, batch: int, check_every: int
) -> None:
    """One entry per root in every list, ``batch`` >= 2 and ``check_every`` >= 1, or one line naming it."""
    if any(len(values) != n for values in lists) or (stops is not None and len(stops) != n):
        raise InvalidParameterError(
            "roots", "simulators, drives, rngs, make_expansions, start_times and stops need one entry per root"
        )
    check_positive_int("check_every", check_every)
    if batch < 2:
        raise InvalidParameterError("batch", f"must be >= 2 to grow trees together, got {batch}")


def _row_models(simulators: Sequence[Simulator], lead: Simulator, propagator: Propagator) -> list[Any] | None:
    """Each root's compiled model, checked to run in one call; ``None`` when every root shares ``lead``.

    Raises:
        IncompatibleModelsError: models the propagator cannot run in one call, before anything is grown.

    """
    if all(simulator is lead for simulator in simulators):
        return None
    models = [require(simulator, CompiledModel, purpose="trees of several roll-outs").model for simulator in simulators]
    check = getattr(propagator, "check_models", None)
    if check is not None:
        check(models)
    return models


def _propagate_together(
    propagator: Propagator,
    task: Task,
    growths: list[_Growth],
    rounds: list[tuple[int, list[_Expansion]]],
    drives: Sequence[np.ndarray],
    start_times: Sequence[float],
    models: list[Any] | None,
) -> np.ndarray:
    """Propagate one round of every growing tree in one call and hand each tree its outcomes.

    Args:
        propagator: the batched propagator every row runs on.
        task: the task (its script drives each row's robot).
        growths: every tree's growth, by tree index.
        rounds: (tree index, that tree's expansions of this round), for every tree still growing.
        drives: each root's drive parameters, shape (n_drive,).
        start_times: each root's time within its roll-out, s.
        models: each root's model (``None``: all rows on the propagator's own model).

    Returns:
        Each tree's share (by propagations) of the call's wall time, s, shape (n_trees,).

    """
    tick = time.perf_counter()
    owners = np.concatenate([np.full(len(round_), j) for j, round_ in rounds])
    rows = [(j, expansion) for j, round_ in rounds for expansion in round_]
    times = np.array([start_times[j] + growths[j].tree.times[expansion[1]] for j, expansion in rows])
    states = np.stack([growths[j].tree.states[expansion[1]] for j, expansion in rows])
    outcomes = _propagate_rows(
        propagator,
        task,
        np.stack([np.asarray(drives[j], dtype=float) for j, _ in rows]),
        states,
        times,
        [expansion for _, expansion in rows],
        growths[0].bounds.control_steps,
        None if models is None else [models[j] for j, _ in rows],
    )
    spent = time.perf_counter() - tick
    at = 0
    for j, round_ in rounds:
        growths[j].offer(round_, outcomes[at : at + len(round_)])
        at += len(round_)
    return spent * np.bincount(owners, minlength=len(growths)) / owners.size
