"""One mechanism for every tree method: pick parents, propagate under random wrenches, cost, store.

Algorithm 1, lines 2-3, for the three methods of :mod:`energy_margin.planning.methods` (EST, Monte
Carlo roll-outs, RRT). Every method shares:

* the random controls: iteration ``i`` draws its wrenches (uniform within the task's bounds) and
  its duration (``max_duration * u**(1/d)``, d the number of perturbed wrench components) from
  blocks of 256 iterations, so the controls are a fixed function of the seed, the method (which
  draws its own uniforms in the same blocks) and the iteration number, whatever the batch size;
* the propagation (:mod:`energy_margin.planning.propagate`: one at a time, or
  :class:`~energy_margin.sim.mujoco_rollout.RolloutPropagator` for a batch) and the acceptance
  test: a reached state outside the task's state box, or not finite, is rejected but still
  consumes the iteration;
* the incremental cost Q of the cost model; a child's cost is its parent's plus Q (costed in
  batches when the field is read, :mod:`energy_margin.planning.nodes`).

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

from energy_margin._renamed import renamed_fields
from energy_margin.errors import Constraint, InvalidParameterError, check_fields, check_positive_int, constrained
from energy_margin.planning.costs import CostModel
from energy_margin.planning.density import Features, ObjectPositions
from energy_margin.planning.nodes import CostField, Outcome, _Tree
from energy_margin.planning.propagate import _Expansion, _propagate_one, _propagate_round, _read
from energy_margin.sim.base import BatchedRollout, Propagator, Simulator, require
from energy_margin.tasks.base import Task
from energy_margin.tasks.command import control_steps
from energy_margin.world.state import FrameState

__all__ = [
    "CostField",
    "Expansion",
    "Outcome",
    "TreeBudget",
    "grow",
]


@renamed_fields(iterations="expansions", max_iterations="max_expansions")
@dataclass(frozen=True)
class TreeBudget:
    """When tree growth stops.

    Attributes:
        expansions: number of expansions (accepted or rejected), or ``None``.
        nodes: number of accepted children of the root, or ``None``.
        max_expansions: hard cap on expansions when only ``nodes`` is given.
        deadline: a ``time.perf_counter()`` reading, s: growth ends at the first round that ends
            after it (checked after every round, without costing the tree), or ``None``.

    """

    expansions: int | None = constrained(300, Constraint("int", minimum=0, optional=True))
    nodes: int | None = constrained(None, Constraint("int", minimum=0, optional=True))
    max_expansions: int = constrained(100_000, Constraint("int", minimum=0))
    deadline: float | None = constrained(None, Constraint("float", optional=True))

    def __post_init__(self) -> None:
        if self.expansions is None and self.nodes is None:
            raise InvalidParameterError("expansions", "and nodes cannot both be None: give expansions, nodes or both")
        check_fields(self)

    @property
    def expansion_limit(self) -> int:
        """Largest number of expansions."""
        return int(self.expansions) if self.expansions is not None else self.max_expansions

    @property
    def node_capacity(self) -> int:
        """Largest number of nodes including the root."""
        limit = self.expansion_limit if self.nodes is None else min(self.nodes, self.expansion_limit)
        return int(limit) + 1


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
        budget: expansions and/or nodes.
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
    bounds = _Bounds.of(simulator, task, cost_model, wrench_scale, duration_scale)
    propagator = _batch_propagator(simulator, cost_model, batch, threads)
    growth = _Growth.plant(simulator, task, root, drive, rng, make_expansion, budget, cost_model, features,
                           propagator, bounds)  # fmt: skip
    expansions, physics_s = growth.run(budget, batch, start_time, stop, check_every)
    return growth.tree.field(expansions, physics_s, started)


@dataclass(frozen=True)
class _Bounds:
    """The controls' bounds and the clock of one growth.

    Attributes:
        max_wrench: largest perturbation wrench per object, shape (n_objects, 6), N and N m.
        max_duration: longest propagation, s.
        dt: simulator time step, s.
        needs_friction: whether the cost model needs the friction work.
        control_steps: steps between two end-effector commands, or ``None`` (one per propagation).

    """

    max_wrench: np.ndarray
    max_duration: float
    dt: float
    needs_friction: bool
    control_steps: int | None

    @classmethod
    def of(
        cls, simulator: Simulator, task: Task, cost_model: CostModel, wrench_scale: float, duration_scale: float
    ) -> _Bounds:
        """The task's bounds times the scales (1: exactly the task's, bit for bit)."""
        limits = task.wrench_limits(simulator.scene)
        max_wrench = limits.max_wrench * wrench_scale if wrench_scale != 1.0 else limits.max_wrench
        max_duration = limits.max_duration * duration_scale
        dt = simulator.timestep
        needs_friction = cost_model.needs_friction_work
        return cls(max_wrench, max_duration, dt, needs_friction, control_steps(task.control_period, dt))


def _batch_propagator(simulator: Simulator, cost_model: CostModel, batch: int, threads: int) -> Propagator | None:
    """The batched propagator when ``batch`` > 1, else ``None``.

    Raises:
        InvalidParameterError: a cost model that needs the friction work, or a simulator without
            batched propagation.

    """
    if batch <= 1:
        return None
    if cost_model.needs_friction_work:
        raise InvalidParameterError(
            "cost", f"must be 'wrench': batched expansion does not integrate friction work, got {cost_model.name!r}"
        )
    return require(simulator, BatchedRollout, purpose="batched expansion").rollout_propagator(threads)


def _plant(
    simulator: Simulator,
    task: Task,
    root: FrameState,
    budget: TreeBudget,
    cost_model: CostModel,
    propagator: Propagator | None,
) -> _Tree:
    """An empty tree of the budget's capacity holding the root, the simulator's current state."""
    first = _read(simulator, needs_energy=cost_model.needs_friction_work)
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
        # The root's own live data: the propagator may belong to another roll-out's simulator.
        first.state = propagator.current_state(getattr(simulator, "data", None))
    tree.set_root(first)
    return tree


@dataclass
class _Growth:
    """The expansion loop: rounds of parents, propagations, and offers to the tree."""

    simulator: Simulator
    task: Task
    drive: np.ndarray
    tree: _Tree
    expansion: Expansion
    controls: _Controls
    features: Features
    root_pos: np.ndarray
    propagator: Propagator | None
    bounds: _Bounds

    limit: int = 0
    deadline: float | None = None
    stop: Callable[[CostField], bool] | None = None
    check_every: int = 1
    expansions: int = 0
    next_check: int = 0
    stopped: bool = False

    @classmethod
    def plant(
        cls,
        simulator: Simulator,
        task: Task,
        root: FrameState,
        drive: np.ndarray,
        rng: np.random.Generator,
        make_expansion: Callable[[np.random.Generator, np.ndarray, Features], Expansion],
        budget: TreeBudget,
        cost_model: CostModel,
        features: Features,
        propagator: Propagator | None,
        bounds: _Bounds,
    ) -> _Growth:
        """A growth whose tree holds ``root`` only (the simulator is reset to it), its method and controls."""
        simulator.reset(root)
        tree = _plant(simulator, task, root, budget, cost_model, propagator)
        root_pos = tree.positions[0].copy()
        expansion = make_expansion(rng, root_pos, features)
        expansion.added(-1, 0, -1, features(tree.positions[0], root_pos))
        controls = _Controls(
            rng, expansion.uniforms, bounds.max_wrench, bounds.max_duration, bounds.dt, budget.expansion_limit
        )
        return cls(simulator, task, drive, tree, expansion, controls, features, root_pos, propagator, bounds)

    def run(
        self,
        budget: TreeBudget,
        batch: int,
        start_time: float,
        stop: Callable[[CostField], bool] | None,
        check_every: int,
    ) -> tuple[int, float]:
        """Expand until the budget, the capacity or ``stop`` ends growth: (expansions, physics wall time in s)."""
        physics_s = 0.0
        self.start(budget, stop, check_every)
        while (round_ := self.next_round(batch)) is not None:
            tick = time.perf_counter()
            outcomes = self._propagate(round_, start_time)
            physics_s += time.perf_counter() - tick
            self.offer(round_, outcomes)
        return self.expansions, physics_s

    def start(self, budget: TreeBudget, stop: Callable[[CostField], bool] | None, check_every: int) -> None:
        """Set the budget and the stopping rule before the first :meth:`next_round`."""
        self.limit, self.deadline = budget.expansion_limit, budget.deadline
        self.stop, self.check_every = stop, check_every
        self.expansions, self.next_check, self.stopped = 0, check_every, False

    def next_round(self, batch: int) -> list[_Expansion] | None:
        """The next round's expansions (at most ``batch``), or ``None`` once growth has ended."""
        tree = self.tree
        if self.stopped or self.expansions >= self.limit or tree.count >= tree.capacity:
            return None
        size = min(batch, self.limit - self.expansions)
        return _next_round(self.expansion, self.controls, tree, self.expansions, size, self.bounds.max_wrench)

    def offer(self, round_: list[_Expansion], outcomes: list[Outcome]) -> None:
        """Offer a round's outcomes to the tree in iteration order, then ask the stopping rule."""
        for (iteration, parent, wrenches, n_steps), outcome in zip(round_, outcomes, strict=True):
            node = self.tree.offer(parent, wrenches, n_steps * self.bounds.dt, outcome)
            if node is None:
                self.expansion.rejected(iteration, parent)
            else:
                self.expansion.added(iteration, node, parent, self.features(outcome.pos, self.root_pos))
        self.expansions += len(round_)
        if self.stop is not None and self.expansions >= self.next_check:
            self.next_check += self.check_every
            self.stopped = bool(self.stop(self.tree.view(self.expansions)))
        if self.deadline is not None and not self.stopped:
            self.stopped = time.perf_counter() >= self.deadline

    def _propagate(self, round_: list[_Expansion], start_time: float) -> list[Outcome]:
        """The outcomes of a round, one at a time or batched."""
        bounds = self.bounds
        if self.propagator is None:
            _, parent, wrenches, n_steps = round_[0]
            return [
                _propagate_one(
                    self.simulator,
                    self.task,
                    self.drive,
                    self.tree,
                    parent,
                    wrenches,
                    n_steps,
                    start_time,
                    bounds.control_steps,
                    bounds.needs_friction,
                )
            ]
        return _propagate_round(
            self.propagator, self.task, self.drive, self.tree, round_, start_time, bounds.control_steps
        )


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
