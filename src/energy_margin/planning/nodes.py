"""The node arrays of a growing tree and the cost field they become.

:class:`_Tree` holds, per node, the simulator state, the object poses and velocities, the robot's
coordinates, the parent, the time and the cost-to-come; :class:`CostField` is what the growth of
:func:`energy_margin.planning.tree.grow` returns, and :class:`Outcome` is what one propagation
reached before it is offered to the tree.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from energy_margin.planning.costs import CostModel, Propagation
from energy_margin.tasks.base import Task

__all__ = ["CostField", "Outcome"]


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
        expansions: expansions (propagations) performed, accepted and rejected.
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
        states: every node's simulator state, shape (M, state_size): :meth:`Simulator.get_state`
            vectors, or the batched propagator's when the tree grew in rounds (``None`` when not
            kept); an engine with :class:`~energy_margin.sim.base.ReleasableStates` frees them
            once growth ends.

    """

    costs: np.ndarray
    object_pos: np.ndarray
    object_vel: np.ndarray
    parents: np.ndarray
    times: np.ndarray
    expansions: int
    physics_s: float
    total_s: float
    object_quat: np.ndarray | None = None
    robot_q: np.ndarray | None = None
    rejected: int = 0
    diverged: int = 0
    states: np.ndarray | None = None

    @property
    def nodes(self) -> int:
        """Number of nodes including the root."""
        return int(self.costs.shape[0])


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

    def view(self, expansions: int) -> CostField:
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
            expansions=expansions,
            physics_s=0.0,
            total_s=0.0,
            robot_q=self._robot_q(count, copy=False),
            rejected=self.rejected,
            diverged=self.diverged,
        )

    def field(self, expansions: int, physics_s: float, started: float) -> CostField:
        self._cost_new_nodes()
        count = self.count
        return CostField(
            costs=self.costs[:count].copy(),
            object_pos=self.positions[:count].copy(),
            object_vel=self.velocities[:count].copy(),
            object_quat=self.quaternions[:count].copy(),
            parents=self.parents[:count].copy(),
            times=self.times[:count].copy(),
            expansions=expansions,
            physics_s=physics_s,
            total_s=time.perf_counter() - started,
            robot_q=self._robot_q(count, copy=True),
            rejected=self.rejected,
            diverged=self.diverged,
            states=self.states[:count].copy(),
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
