"""Success continuation: the task's scripted motion continued from a tree's likely states.

A tree reaches about a second past its frame; a success region the nominal motion reaches later
holds none of its states, and the success score stays 0. :func:`continued_success` draws nodes of
the tree by likelihood weight, continues the task's scripted motion from each node's state without
perturbation to the end of the motion (the task's ``duration``) or a horizon, and returns the
fraction of draws whose continuation ends in the success region: a Monte Carlo estimate of the
likelihood-weighted probability that the motion still succeeds from the tree's states.

The continuations run together through ``mujoco.rollout`` when the simulator offers it
(:class:`~energy_margin.sim.base.BatchedRollout`), else one at a time through the simulator. The
command (:func:`~energy_margin.tasks.command.command_robot`, without random variation) is
re-evaluated every step, as the data generator does: held for a control period instead, a stiff
servo's targets jump and jerk what the robot carries (a Panda's tray of boxes flies apart where the
recorded roll-out keeps them).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from energy_margin.analysis.scores import likelihood
from energy_margin.errors import InvalidParameterError, check_float, check_int
from energy_margin.planning import CostField
from energy_margin.sim.base import BatchedRollout, Propagator, Simulator
from energy_margin.tasks import Task
from energy_margin.tasks.command import command_robot, control_steps
from energy_margin.world.state import FrameState

__all__ = [
    "Continuation",
    "Controller",
    "continuation_seed",
    "continued_success",
    "continued_successes_together",
    "controlled_success",
]

#: What runs a continuation under feedback: called every control period with the simulator, it
#: sets the robot's command from the simulator's current state (``set_model_command``).
Controller = Callable[[Simulator], None]

#: Spawn key of the continuation's draws under the frame's seed (the tree's generator is the seed's own).
_SPAWN_KEY = (0xC0,)


def continuation_seed(seed: int) -> np.random.SeedSequence:
    """The seed sequence of a frame's continuation draws, independent of its tree's generator."""
    return np.random.SeedSequence(seed, spawn_key=_SPAWN_KEY)


@dataclass(frozen=True)
class Continuation:
    """What a frame's continuations found.

    Attributes:
        success_score: fraction of the draws whose continuation ends in the success region, in [0, 1].
        nodes: the distinct nodes continued.
        steps: simulator steps of the longest continuation.

    """

    success_score: float
    nodes: int
    steps: int


def _steps(
    end: float, dt: float, field: CostField, nodes: np.ndarray, start_time: float, horizon: float | None
) -> np.ndarray:
    """Steps of each node's continuation: to ``end`` (s on the frame's clock) or the horizon, at least one."""
    remaining = end - (start_time + field.times[nodes])
    if horizon is not None:
        remaining = np.minimum(remaining, horizon)
    return np.maximum(np.round(remaining / dt).astype(np.int64), 1)


_Ends = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


@dataclass(frozen=True)
class _Draws:
    """A frame's continuation draws: the distinct nodes, how often each was drawn, steps and start times."""

    nodes: np.ndarray
    counts: np.ndarray
    n_steps: np.ndarray
    times: np.ndarray


def _draw(
    task: Task, dt: float, field: CostField, *, lam: float, samples: int, seed: int, start_time: float,
    horizon: float | None, end: float | None = None,
) -> _Draws:  # fmt: skip
    """Draw ``samples`` nodes of ``field`` by likelihood (checked arguments; see :func:`continued_success`).

    ``end``: when the continuations end on the frame's clock, s (``None``: the task's ``duration``).
    """
    check_int("samples", samples, minimum=1)
    if horizon is not None:
        check_float("horizon", horizon, minimum=0.0, exclusive_minimum=True)
    if field.states is None:
        raise InvalidParameterError("field", "holds no node states to continue from")
    rng = np.random.default_rng(continuation_seed(seed))
    draws = rng.choice(field.nodes, size=samples, p=likelihood(field.costs, lam))
    nodes, counts = np.unique(draws, return_counts=True)
    n_steps = _steps(task.config.duration if end is None else end, dt, field, nodes, start_time, horizon)
    return _Draws(nodes, counts, n_steps, start_time + field.times[nodes])


def _scored(task: Task, root: FrameState, draws: _Draws, samples: int, ends: _Ends) -> Continuation:
    pos, vel, quat, robot = ends
    inside = np.asarray(task.success_inside(root, pos, vel, quat, robot), dtype=bool)
    score = float(np.sum(draws.counts[inside])) / samples
    return Continuation(success_score=score, nodes=int(draws.nodes.size), steps=int(draws.n_steps.max()))


def continued_success(
    simulator: Simulator,
    task: Task,
    root: FrameState,
    field: CostField,
    drive: np.ndarray,
    *,
    lam: float,
    samples: int,
    seed: int,
    start_time: float = 0.0,
    horizon: float | None = None,
    batched_states: bool = False,
    threads: int = 1,
) -> Continuation:
    """Success score of ``samples`` continuations of the scripted motion from nodes drawn by likelihood.

    Args:
        simulator: the simulator the tree grew on (its states are ``field.states``).
        task: the task (script, success region, timestep, duration).
        root: the analysed frame z_init (the success region may follow it).
        field: the tree's cost field, with its node states.
        drive: the trajectory's drive parameters.
        lam: the likelihood's inverse temperature, 1/J.
        samples: draws (with replacement) by likelihood weight, >= 1.
        seed: the frame's seed (the draws use :func:`continuation_seed`).
        start_time: time of the frame within its roll-out, s.
        horizon: longest continuation, s past the node; ``None``: to the task's ``duration``.
        batched_states: ``field.states`` are the batched propagator's (a tree grown in rounds).
        threads: ``mujoco.rollout`` threads.

    Raises:
        InvalidParameterError: ``samples`` < 1, a non-positive horizon, or a field without states.

    """
    draws = _draw(task, simulator.timestep, field, lam=lam, samples=samples, seed=seed, start_time=start_time,
                  horizon=horizon)  # fmt: skip
    drive = np.asarray(drive, dtype=float)
    where = (draws.nodes, draws.times, draws.n_steps)
    if isinstance(simulator, BatchedRollout):
        ends = _continue_batched(simulator, task, field, *where, drive, batched_states, threads)
    else:
        ends = _continue_one_by_one(simulator, task, field, *where, drive)
    return _scored(task, root, draws, samples, ends)


def continued_successes_together(
    propagating: BatchedRollout,
    task: Task,
    roots: Sequence[FrameState],
    fields: Sequence[CostField],
    drives: Sequence[np.ndarray],
    models: Sequence[Any],
    *,
    lam: float,
    samples: int,
    seeds: Sequence[int],
    start_times: Sequence[float],
    horizon: float | None = None,
) -> list[Continuation]:
    """:func:`continued_success` of many frames of one scene, every continuation in one batched call.

    Each frame's score is the one :func:`continued_success` gives it alone on its own simulator
    with the same seed (``batched_states``: the fields are trees grown in rounds); only where the
    continuations run changes.

    Args:
        propagating: the simulator whose batched propagator runs the call.
        task: the task.
        roots: each frame's state z_init.
        fields: each frame's cost field, with the batched propagator's node states.
        drives: each frame's drive parameters, shape (n_drive,).
        models: each frame's compiled model (its roll-out's; differing from ``propagating``'s in
            numbers only).
        lam: the likelihood's inverse temperature, 1/J.
        samples: draws per frame, >= 1.
        seeds: each frame's seed.
        start_times: each frame's time within its roll-out, s.
        horizon: longest continuation, s past the node; ``None``: to the task's ``duration``.

    """
    dt = propagating.timestep  # type: ignore[attr-defined]
    draws = [
        _draw(task, dt, field, lam=lam, samples=samples, seed=seed, start_time=start, horizon=horizon)
        for field, seed, start in zip(fields, seeds, start_times, strict=True)
    ]
    rows = [draw.nodes.size for draw in draws]
    states = np.concatenate([field.states[draw.nodes] for field, draw in zip(fields, draws, strict=True)])  # type: ignore[index]
    pos, vel, quat, robot = _unperturbed_ends(
        propagating.rollout_propagator(1),
        task,
        np.repeat(np.asarray(drives, dtype=float), rows, axis=0),
        states,
        np.concatenate([draw.times for draw in draws]),
        np.concatenate([draw.n_steps for draw in draws]),
        fields[0].object_pos.shape[1],
        [model for model, count in zip(models, rows, strict=True) for _ in range(count)],
    )
    bounds = np.cumsum([0, *rows])
    return [
        _scored(task, root, draw, samples, (pos[a:b], vel[a:b], quat[a:b], robot[a:b]))
        for root, draw, a, b in zip(roots, draws, bounds[:-1], bounds[1:], strict=True)
    ]


def _continue_batched(
    simulator: BatchedRollout,
    task: Task,
    field: CostField,
    nodes: np.ndarray,
    times: np.ndarray,
    n_steps: np.ndarray,
    drive: np.ndarray,
    batched_states: bool,
    threads: int,
) -> _Ends:
    """End objects and robot of the continuations, rolled out together through ``mujoco.rollout``."""
    assert field.states is not None
    propagator = simulator.rollout_propagator(threads)
    if batched_states:
        states = field.states[nodes]
    else:
        # The simulator's own vectors: restore each and read it back as the propagator's.
        plain: Simulator = simulator  # type: ignore[assignment]
        states = np.empty((nodes.size, propagator.state_size))
        for row, node in enumerate(nodes.tolist()):
            plain.set_state(field.states[node])
            states[row] = propagator.current_state()
    return _unperturbed_ends(propagator, task, drive, states, times, n_steps, field.object_pos.shape[1])


def _unperturbed_ends(
    propagator: Propagator,
    task: Task,
    drive: np.ndarray,
    states: np.ndarray,
    times: np.ndarray,
    n_steps: np.ndarray,
    n_objects: int,
    models: list[Any] | None = None,
) -> _Ends:
    """End objects and robot of ``states`` continued without wrenches, commanded every step as generated.

    ``drive``: one roll-out's (n_drive,) or each row's (k, n_drive); ``models``: each row's model,
    or the propagator's when ``None``.
    """
    wrenches = np.zeros((states.shape[0], n_objects, 6))
    pos, vel, quat, final = propagator.propagate(task, drive, states, times, wrenches, n_steps, 1, models)
    return pos, vel, quat, propagator.end_robot_positions(final)


def _end_of(simulator: Simulator) -> tuple[np.ndarray, ...]:
    """The objects' positions, velocities, quaternions and the robot's positions where a continuation ended."""
    return (
        simulator.object_positions().copy(),
        simulator.object_velocities().copy(),
        simulator.object_quaternions().copy(),
        simulator.robot_positions().copy(),
    )


def _stacked(ends: list[tuple[np.ndarray, ...]]) -> _Ends:
    """One array per quantity of :func:`_end_of`, a row per continuation."""
    pos, vel, quat, robot = (np.stack(column) for column in zip(*ends, strict=True))
    return pos, vel, quat, robot


def _continue_one_by_one(
    simulator: Simulator,
    task: Task,
    field: CostField,
    nodes: np.ndarray,
    times: np.ndarray,
    n_steps: np.ndarray,
    drive: np.ndarray,
) -> _Ends:
    """End objects and robot of the continuations, one at a time through the simulator."""
    assert field.states is not None
    dt = simulator.timestep
    n_objects = field.object_pos.shape[1]
    ends: list[tuple[np.ndarray, ...]] = []
    for node, start, steps in zip(nodes.tolist(), times.tolist(), n_steps.tolist(), strict=True):
        simulator.set_state(field.states[node])
        # A node's state holds the wrenches of the propagation that reached it: none from here on.
        simulator.set_object_wrenches(np.zeros((n_objects, 6)))
        for step in range(steps):
            command_robot(task, simulator, drive, start + step * dt, None)
            simulator.step(1)
        ends.append(_end_of(simulator))
    return _stacked(ends)


def controlled_success(
    simulator: Simulator,
    task: Task,
    root: FrameState,
    field: CostField,
    controllers: Callable[[], Controller],
    *,
    lam: float,
    samples: int,
    seed: int,
    horizon: float,
    period: float,
) -> Continuation:
    """Success score of ``samples`` continuations under a feedback controller, from nodes drawn by likelihood.

    The draws are :func:`continued_success`'s (the same nodes for the same seed). Each draw's
    continuation starts at its node's state without wrenches, with a controller of its own
    (``controllers()``, e.g. a copy of a policy that keeps state) that sets the command every
    ``period`` from the state reached, and runs to ``horizon`` past the frame (at least one step);
    success is scored where it ends. One continuation at a time: the command depends on the state.

    Args:
        simulator: the simulator the tree grew on (its states are ``field.states``).
        task: the task (success region).
        root: the analysed frame z_init (the success region may follow it).
        field: the tree's cost field, with its node states.
        controllers: makes the controller of one continuation.
        lam: the likelihood's inverse temperature, 1/J.
        samples: draws (with replacement) by likelihood weight, >= 1.
        seed: the frame's seed (the draws use :func:`continuation_seed`).
        horizon: when the continuations end, s after the frame, > 0.
        period: time between two commands, s, > 0 (rounded to whole time steps, at least one).

    Raises:
        InvalidParameterError: ``samples`` < 1, a non-positive horizon or period, or a field without states.

    """
    check_float("horizon", horizon, minimum=0.0, exclusive_minimum=True)
    check_float("period", period, minimum=0.0, exclusive_minimum=True)
    dt = simulator.timestep
    draws = _draw(task, dt, field, lam=lam, samples=samples, seed=seed, start_time=0.0, horizon=None, end=horizon)
    assert field.states is not None
    every = control_steps(period, dt) or 1
    n_objects = field.object_pos.shape[1]
    ends: list[tuple[np.ndarray, ...]] = []
    for node, steps in zip(draws.nodes.tolist(), draws.n_steps.tolist(), strict=True):
        simulator.set_state(field.states[node])
        simulator.set_object_wrenches(np.zeros((n_objects, 6)))
        control = controllers()
        for step in range(0, steps, every):  # a command, then the physics steps it is held
            control(simulator)
            simulator.step(min(every, steps - step))
        ends.append(_end_of(simulator))
    return _scored(task, root, draws, samples, _stacked(ends))
