"""One mechanism for every tree method: pick parents, propagate under random wrenches, cost, store.

Algorithm 1, lines 2-3, for the three methods of :mod:`energy_margin.planning.methods` (EST, Monte
Carlo roll-outs, RRT). Every method shares:

* the random controls: iteration ``i`` draws its wrenches (uniform within the task's bounds) and
  its duration (``max_duration * u**(1/d)``, d the number of perturbed wrench components) from
  blocks of 256 iterations, so the controls are a fixed function of the seed, the method (which
  draws its own uniforms in the same blocks) and the iteration number, whatever the batch size;
* the propagation (:func:`_propagate_one`, or :class:`~energy_margin.sim.mujoco_rollout.RolloutPropagator`
  for a batch) and the acceptance test: a reached state outside the task's state box, or not
  finite, is rejected but still consumes the iteration;
* the incremental cost Q of the cost model; a child's cost is its parent's plus Q (costed in
  batches when the field is read, :class:`_Tree`).

Only the choice of the parent differs between methods (:class:`Expansion`).

Batched expansion (``batch`` B > 1): each round picks the parents of B iterations against the tree
as it stands, propagates them together through ``mujoco.rollout`` (multithreaded, outside the GIL)
and then adds the accepted children in iteration order. The controls of an iteration are the same
as with B = 1, but the parents differ (a round cannot pick a node created in the same round), so
the tree differs from the one-at-a-time tree; it is a fixed function of the seed and B, and does
not depend on the number of threads. See docs/results/budget.md.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from energy_margin.errors import InvalidParameterError, check_int, check_positive_int
from energy_margin.planning.costs import CostModel, Propagation
from energy_margin.planning.density import Features, ObjectPositions
from energy_margin.sim.base import BatchedRollout, Propagator, Simulator, require
from energy_margin.tasks.base import Task, command_robot
from energy_margin.world.state import FrameState

__all__ = [
    "CostField",
    "Expansion",
    "Outcome",
    "TreeBudget",
    "grow",
]


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
            raise InvalidParameterError("iterations", "and nodes cannot both be None: give iterations, nodes or both")
        for name in ("iterations", "nodes"):
            value = getattr(self, name)
            if value is not None:
                check_int(name, value, minimum=0)

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
        parents: parent index of every node (-1 for the root), shape (M,); a parent always
            precedes its children.
        times: simulated time of every node, shape (M,), s.
        iterations: expansions (propagations) performed, accepted and rejected.
        physics_s: wall time spent inside the simulator, s.
        total_s: wall time of the whole growth, s.
        object_quat: object orientations of every node, shape (M, n_objects, 4), ``(w, x, y, z)``
            (``None`` when not kept); regions that test geometry (``contact``) use them.
        robot_q: the robot's coordinates at every node (as ``FrameState.robot_q``), shape
            (M, n_robot); ``None`` when not kept (batched expansion of a model whose propagator
            does not return them). Regions that follow the robot use them.
        rejected: reached states rejected for leaving the task's state box (an object outside
            its bounds or faster than its speed bound).
        diverged: reached states rejected for holding a non-finite number (the simulation blew up).

    """

    costs: np.ndarray
    object_pos: np.ndarray
    object_vel: np.ndarray
    parents: np.ndarray
    times: np.ndarray
    iterations: int
    physics_s: float
    total_s: float
    object_quat: np.ndarray | None = None
    robot_q: np.ndarray | None = None
    rejected: int = 0
    diverged: int = 0

    @property
    def nodes(self) -> int:
        """Number of nodes including the root."""
        return int(self.costs.shape[0])


class Expansion(Protocol):
    """How a tree method chooses the node each iteration extends.

    Attributes:
        uniforms: uniform numbers in [0, 1) the method consumes per iteration (drawn with the
            controls, in blocks).

    """

    uniforms: int

    def parent(self, iteration: int, uniforms: np.ndarray, count: int) -> int | None:
        """The node iteration ``iteration`` extends, or ``None`` when it depends on a pending one.

        Args:
            iteration: 0-based iteration number.
            uniforms: this iteration's ``uniforms`` numbers.
            count: nodes in the tree now (the parent is an index below it).

        ``None`` is only returned while earlier iterations of the same round are pending: the
        round then ends before this iteration.
        """
        ...

    def added(self, iteration: int, node: int, parent: int, features: np.ndarray) -> None:
        """Iteration ``iteration`` added ``node`` (a child of ``parent``) with density features."""
        ...

    def rejected(self, iteration: int, parent: int) -> None:
        """Iteration ``iteration``'s child of ``parent`` was rejected."""
        ...


@dataclass
class Outcome:
    """What one propagation reached."""

    pos: np.ndarray
    vel: np.ndarray
    quat: np.ndarray
    energy: float
    friction_work: float
    state: np.ndarray
    robot: np.ndarray | None = None  # the robot's coordinates (``FrameState.robot_q``), when known


class _Tree:
    """Growing node arrays; ``offer`` tests a reached state and stores it.

    Costs are computed lazily: a node keeps its wrenches and its propagation's energies, and the
    nodes added since the last look are costed together by the cost model's vectorised
    ``increments`` when the field is read (a convergence check or the end), which saves a
    cost-model call per expansion; the values are those of one call per node.
    """

    def __init__(
        self, capacity: int, state_size: int, n_objects: int, n_robot: int, task: Task, cost_model: CostModel
    ) -> None:
        self.states = np.empty((capacity, state_size))
        self.robots = np.full((capacity, n_robot), np.nan)
        self.robots_known = True
        self.costs = np.empty(capacity)
        self.parents = np.empty(capacity, dtype=np.int64)
        self.times = np.empty(capacity)
        self.positions = np.empty((capacity, n_objects, 3))
        self.velocities = np.empty((capacity, n_objects, 6))
        self.quaternions = np.empty((capacity, n_objects, 4))
        self.energies = np.zeros(capacity)
        self.wrenches = np.zeros((capacity, n_objects, 6))
        self.friction_works = np.zeros(capacity)
        self.capacity = capacity
        self.count = 0
        self.costed = 0
        self.rejected = 0
        self.diverged = 0
        self.task = task
        self.cost_model = cost_model

    def set_root(self, outcome: Outcome) -> None:
        self.states[0] = outcome.state
        self.costs[0], self.parents[0], self.times[0] = 0.0, -1, 0.0
        self.positions[0] = outcome.pos
        self.velocities[0] = outcome.vel
        self.quaternions[0] = outcome.quat
        self.energies[0] = outcome.energy
        self._keep_robot(0, outcome)
        self.count = self.costed = 1

    def offer(self, parent: int, wrenches: np.ndarray, duration: float, outcome: Outcome) -> int | None:
        """Add the reached state as a child of ``parent``; its index, or ``None`` when rejected."""
        if self.count >= self.capacity:
            return None
        pos, vel = outcome.pos, outcome.vel
        if not np.isfinite(pos.sum() + vel.sum()):
            self.diverged += 1
            return None
        if not self.task.within_bounds(pos, vel):
            self.rejected += 1
            return None
        node = self.count
        self.states[node] = outcome.state
        self.parents[node] = parent
        self.times[node] = self.times[parent] + duration
        self.positions[node] = pos
        self.velocities[node] = vel
        self.quaternions[node] = outcome.quat
        self.energies[node] = outcome.energy
        self.wrenches[node] = wrenches
        self.friction_works[node] = outcome.friction_work
        self._keep_robot(node, outcome)
        self.count += 1
        return node

    def _keep_robot(self, node: int, outcome: Outcome) -> None:
        robot = outcome.robot
        if robot is None or robot.shape != self.robots.shape[1:]:
            self.robots_known = False
        else:
            self.robots[node] = robot

    def _robot_q(self, count: int, *, copy: bool) -> np.ndarray | None:
        if not self.robots_known:
            return None
        return self.robots[:count].copy() if copy else self.robots[:count]

    def _cost_new_nodes(self) -> None:
        """Cost-to-come of the nodes added since the last call (a child's is its parent's plus Q)."""
        first, count = self.costed, self.count
        if first >= count:
            return
        parents = self.parents[first:count]
        stacked = Propagation(
            wrenches=self.wrenches[first:count],
            pos_before=self.positions[parents],
            pos_after=self.positions[first:count],
            quat_before=self.quaternions[parents],
            quat_after=self.quaternions[first:count],
            energy_before=self.energies[parents],
            energy_after=self.energies[first:count],
            friction_work=self.friction_works[first:count],
        )
        batched = getattr(self.cost_model, "increments", None)
        if batched is not None:
            increments = np.asarray(batched(stacked), dtype=float)
        else:
            # A cost model of one's own that only costs one propagation at a time.
            increments = np.array([self.cost_model(_one(stacked, j)) for j in range(count - first)], dtype=float)
        costs = self.costs
        # In index order: a parent precedes its children, and may itself be new.
        for node, parent, increment in zip(range(first, count), parents.tolist(), increments.tolist(), strict=True):
            costs[node] = costs[parent] + increment
        self.costed = count

    def view(self, iterations: int) -> CostField:
        """The nodes so far, without copies or timings (valid until the next ``offer``)."""
        self._cost_new_nodes()
        count = self.count
        return CostField(
            costs=self.costs[:count],
            object_pos=self.positions[:count],
            object_vel=self.velocities[:count],
            object_quat=self.quaternions[:count],
            parents=self.parents[:count],
            times=self.times[:count],
            iterations=iterations,
            physics_s=0.0,
            total_s=0.0,
            robot_q=self._robot_q(count, copy=False),
            rejected=self.rejected,
            diverged=self.diverged,
        )

    def field(self, iterations: int, physics_s: float, started: float) -> CostField:
        self._cost_new_nodes()
        count = self.count
        return CostField(
            costs=self.costs[:count].copy(),
            object_pos=self.positions[:count].copy(),
            object_vel=self.velocities[:count].copy(),
            object_quat=self.quaternions[:count].copy(),
            parents=self.parents[:count].copy(),
            times=self.times[:count].copy(),
            iterations=iterations,
            physics_s=physics_s,
            total_s=time.perf_counter() - started,
            robot_q=self._robot_q(count, copy=True),
            rejected=self.rejected,
            diverged=self.diverged,
        )


def _one(stacked: Propagation, index: int) -> Propagation:
    """Propagation ``index`` of stacked ones."""
    return Propagation(
        wrenches=stacked.wrenches[index],
        pos_before=stacked.pos_before[index],
        pos_after=stacked.pos_after[index],
        quat_before=stacked.quat_before[index],
        quat_after=stacked.quat_after[index],
        energy_before=float(np.asarray(stacked.energy_before)[index]),
        energy_after=float(np.asarray(stacked.energy_after)[index]),
        friction_work=float(np.asarray(stacked.friction_work)[index]),
    )


class _Controls:
    """Per-iteration random numbers, drawn in blocks of 256 iterations (a fixed stream per seed)."""

    block = 256

    def __init__(
        self,
        rng: np.random.Generator,
        uniforms: int,
        max_wrench: np.ndarray,
        max_duration: float,
        dt: float,
        limit: int,
    ) -> None:
        self.rng = rng
        self.n_uniforms = uniforms
        self.max_wrench = max_wrench
        self.max_duration = max_duration
        self.exponent = 1.0 / max(int(np.count_nonzero(max_wrench)), 1)
        self.dt = dt
        self.limit = limit
        self._start = -1
        self.uniforms = np.empty((0, uniforms))
        self.unit_wrenches = np.empty((0, *max_wrench.shape))
        self.steps = np.empty(0, dtype=np.int64)

    def slot(self, iteration: int) -> int:
        """Index of ``iteration`` in the current block (iterations must be visited in order)."""
        slot = iteration % self.block
        if slot == 0 and iteration != self._start:
            self._start = iteration
            size = min(self.block, self.limit - iteration)
            rng = self.rng
            self.uniforms = rng.random((size, self.n_uniforms))
            self.unit_wrenches = rng.uniform(-1.0, 1.0, (size, *self.max_wrench.shape))
            self.steps = np.maximum(
                1, (self.max_duration * rng.random(size) ** self.exponent / self.dt).astype(np.int64)
            )
        return slot


def _read(simulator: Simulator, *, needs_energy: bool) -> Outcome:
    return Outcome(
        pos=simulator.object_positions().copy(),
        vel=simulator.object_velocities(),
        quat=simulator.object_quaternions().copy(),
        energy=simulator.mechanical_energy() if needs_energy else 0.0,
        friction_work=0.0,
        state=simulator.get_state(),
        robot=simulator.robot_positions(),
    )


def grow(
    simulator: Simulator,
    task: Task,
    root: FrameState,
    drive: np.ndarray,
    rng: np.random.Generator,
    make_expansion: Callable[[np.random.Generator, np.ndarray, Features], Expansion],
    *,
    budget: TreeBudget,
    cost_model: CostModel,
    features: Features | None = None,
    start_time: float = 0.0,
    batch: int = 1,
    threads: int = 1,
    stop: Callable[[CostField], bool] | None = None,
    check_every: int = 25,
    wrench_scale: float = 1.0,
    duration_scale: float = 1.0,
) -> CostField:
    """Grow a tree from ``root`` with the parent choice of ``make_expansion`` and return its cost field.

    Args:
        simulator: a simulator built from the frame's scene.
        task: the task (wrench ranges, state box, nominal end-effector command).
        root: the frame state z_init.
        drive: the trajectory's drive parameters, shape (n_drive,).
        rng: the analysis' random generator (consumed in a fixed order).
        make_expansion: builds the method from ``(rng, root_features, features)``; it may draw from
            ``rng`` (before any control is drawn).
        budget: iterations and/or nodes.
        cost_model: incremental cost Q.
        features: features of a node's object positions (density, nearest neighbour); every
            object's displacement from the root by default.
        start_time: time of the frame within its roll-out, s (the end-effector's script clock).
        batch: iterations propagated together per round, >= 1 (1: one at a time).
        threads: ``mujoco.rollout`` threads when ``batch`` > 1.
        stop: an early-stopping rule: called with the cost field so far (without timings) every
            ``check_every`` expansions; growth ends when it returns ``True`` (the budget stays the
            upper bound). The tree does not know why: scores and tolerances belong to the caller.
        check_every: expansions between two calls of ``stop``, >= 1.
        wrench_scale: factor on the task's perturbation wrench bounds.
        duration_scale: factor on the task's longest perturbation propagation, s.

    The end-effector keeps following its script: its command (:func:`command_robot`, without random
    variation) is evaluated at ``start_time`` plus the node's time when a propagation starts, and
    again every :attr:`Task.control_period` seconds within it when the task sets one.

    Raises:
        InvalidParameterError: ``batch`` > 1 with a cost model that needs the friction work, or a simulator
            without batched propagation.

    """
    started = time.perf_counter()
    check_positive_int("batch", batch)
    check_positive_int("threads", threads)
    check_positive_int("check_every", check_every)
    features = features if features is not None else ObjectPositions()
    limits = task.wrench_limits(simulator.scene)
    # The scales multiply the task's bounds (1: exactly the task's, bit for bit).
    max_wrench = limits.max_wrench * wrench_scale if wrench_scale != 1.0 else limits.max_wrench
    max_duration = limits.max_duration * duration_scale
    dt = simulator.timestep
    needs_friction = cost_model.needs_friction_work
    control_steps = max(1, round(task.control_period / dt)) if task.control_period is not None else None

    simulator.reset(root)
    propagator: Propagator | None = None
    if batch > 1:
        if needs_friction:
            raise InvalidParameterError(
                "cost", f"must be 'wrench': batched expansion does not integrate friction work, got {cost_model.name!r}"
            )
        propagator = require(simulator, BatchedRollout, purpose="batched expansion").rollout_propagator(threads)
    first = _read(simulator, needs_energy=needs_friction)
    assert first.robot is not None
    tree = _Tree(
        budget.node_capacity,
        propagator.state_size if propagator is not None else simulator.state_size,
        root.n_objects,
        first.robot.size,
        task,
        cost_model,
    )
    if propagator is not None:
        first.state = propagator.current_state()
    tree.set_root(first)
    root_pos = tree.positions[0].copy()
    expansion = make_expansion(rng, root_pos, features)
    expansion.added(-1, 0, -1, features(tree.positions[0], root_pos))
    limit = budget.iteration_limit
    controls = _Controls(rng, expansion.uniforms, max_wrench, max_duration, dt, limit)

    iterations = 0
    physics_s = 0.0
    next_check = check_every
    while iterations < limit and tree.count < tree.capacity:
        round_ = _next_round(expansion, controls, tree, iterations, min(batch, limit - iterations), max_wrench)
        tick = time.perf_counter()
        if propagator is None:
            _, parent, wrenches, n_steps = round_[0]
            outcomes = [
                _propagate_one(
                    simulator, task, drive, tree, parent, wrenches, n_steps, start_time, control_steps, needs_friction
                )
            ]
        else:
            outcomes = _propagate_round(propagator, task, drive, tree, round_, start_time, control_steps)
        physics_s += time.perf_counter() - tick
        for (iteration, parent, wrenches, n_steps), outcome in zip(round_, outcomes, strict=True):
            node = tree.offer(parent, wrenches, n_steps * dt, outcome)
            if node is None:
                expansion.rejected(iteration, parent)
            else:
                expansion.added(iteration, node, parent, features(outcome.pos, root_pos))
        iterations += len(round_)
        if stop is not None and iterations >= next_check:
            next_check += check_every
            if stop(tree.view(iterations)):
                break
    return tree.field(iterations, physics_s, started)


#: One expansion of a round: (iteration, parent node, wrench (6,), propagation steps).
_Expansion = tuple[int, int, np.ndarray, int]


def _next_round(
    expansion: Expansion, controls: _Controls, tree: _Tree, iterations: int, size: int, max_wrench: np.ndarray
) -> list[_Expansion]:
    """The parents and controls of the next round: up to ``size`` expansions from iteration ``iterations``.

    A round ends early when the method has no parent for an iteration (it waits for the outcomes
    of the round); the first iteration of a round always has one.
    """
    round_: list[_Expansion] = []
    while len(round_) < size:
        iteration = iterations + len(round_)
        slot = controls.slot(iteration)
        parent = expansion.parent(iteration, controls.uniforms[slot], tree.count)
        if parent is None:
            break
        round_.append((iteration, parent, controls.unit_wrenches[slot] * max_wrench, int(controls.steps[slot])))
    if not round_:
        raise AssertionError("an expansion method returned no parent for the first iteration of a round")
    return round_


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
    pos, vel, quat, states = propagator.propagate(
        task,
        drive,
        tree.states[[parent for _, parent, _, _ in round_]],
        np.array([start_time + tree.times[parent] for _, parent, _, _ in round_]),
        np.stack([wrenches for _, _, wrenches, _ in round_]),
        np.array([n_steps for _, _, _, n_steps in round_]),
        control_steps,
    )
    robots = propagator.object_states(states)[3]  # joint coordinates (a model's mocap poses are not among them)
    return [Outcome(pos[j], vel[j], quat[j], 0.0, 0.0, states[j], robots[j]) for j in range(len(round_))]


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
