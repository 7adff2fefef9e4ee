from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pytest

from energy_margin.analysis.frame import AnalyzerConfig, analyze_frame, score_field
from energy_margin.analysis.scores import region_score
from energy_margin.errors import InvalidParameterError
from energy_margin.planning import CostField, TreeBudget, grow_tree
from energy_margin.planning.costs import MIN_COST, CostModel, EnergyBalanceCost, Propagation, WrenchWorkCost
from energy_margin.sim import Simulator
from energy_margin.sim.mujoco_backend import MujocoSimulator
from energy_margin.tasks import PushingTask, RobotState, Task, TaskConfig, Trajectory, WrenchLimits
from energy_margin.tasks.state_box import StateBox
from energy_margin.world.scene import Geom, RigidObject, Scene
from energy_margin.world.state import FrameState

# ---------------------------------------------------------------- a faked world


@dataclass(frozen=True)
class Propagated:
    wrench: np.ndarray
    before: np.ndarray
    after: np.ndarray
    steps: int


class PointMassSimulator:
    """Point masses without contacts or gravity, semi-implicit Euler: the Simulator protocol faked."""

    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        n = scene.n_objects
        self.mass = scene.object_masses
        self.pos = np.zeros((n, 3))
        self.vel = np.zeros((n, 3))
        self.wrench = np.zeros((n, 6))
        self.time = 0.0
        self.resets = 0
        self.propagations: list[Propagated] = []

    @property
    def timestep(self) -> float:
        return self.scene.timestep

    @property
    def state_size(self) -> int:
        return 1 + 12 * self.scene.n_objects

    def reset(self, frame: FrameState) -> None:
        self.pos = np.array(frame.object_pos, dtype=float)
        self.vel = np.array(frame.object_vel[:, :3], dtype=float)
        self.wrench = np.zeros_like(self.wrench)
        self.time = 0.0
        self.resets += 1

    def diverged(self) -> bool:
        return not bool(np.all(np.isfinite(self.get_state())))

    def get_state(self) -> np.ndarray:
        return np.concatenate([[self.time], self.pos.ravel(), self.vel.ravel(), self.wrench.ravel()])

    def set_state(self, state: np.ndarray) -> None:
        n = self.scene.n_objects
        self.time = float(state[0])
        self.pos = state[1 : 1 + 3 * n].reshape(n, 3).copy()
        self.vel = state[1 + 3 * n : 1 + 6 * n].reshape(n, 3).copy()
        self.wrench = state[1 + 6 * n :].reshape(n, 6).copy()

    def set_object_wrenches(self, wrenches: np.ndarray) -> None:
        self.wrench = np.array(wrenches, dtype=float)

    def set_robot_force(self, force: np.ndarray) -> None:
        assert force.shape == (0,)

    def set_robot_targets(self, targets: np.ndarray) -> None:
        del targets

    def object_penetrations(self) -> list[tuple[int, int, float]]:
        return []

    def step(self, n_steps: int, *, track_friction_work: bool = False) -> float:
        before = self.pos.copy()
        for _ in range(n_steps):
            self.vel += self.wrench[:, :3] / self.mass[:, None] * self.timestep
            self.pos += self.vel * self.timestep
            self.time += self.timestep
        self.propagations.append(Propagated(self.wrench.copy(), before, self.pos.copy(), n_steps))
        return 0.0

    def object_positions(self) -> np.ndarray:
        return self.pos.copy()

    def object_quaternions(self) -> np.ndarray:
        return np.tile([1.0, 0.0, 0.0, 0.0], (self.scene.n_objects, 1))

    def object_velocities(self) -> np.ndarray:
        return np.concatenate([self.vel, np.zeros_like(self.vel)], axis=1)

    def robot_positions(self) -> np.ndarray:
        return np.zeros(0)

    def robot_velocities(self) -> np.ndarray:
        return np.zeros(0)

    def mechanical_energy(self) -> float:
        return 0.5 * float(np.sum(self.mass * np.sum(self.vel**2, axis=1)))

    def frame_state(self) -> FrameState:
        return FrameState(
            self.pos.copy(), self.object_quaternions(), self.object_velocities(), np.zeros(0), np.zeros(0)
        )


class HalfSpace:
    def __init__(self, axis: int, threshold: float, below: bool) -> None:
        self.axis, self.threshold, self.below = axis, threshold, below

    def contains(self, positions: np.ndarray, velocities: np.ndarray | None = None) -> np.ndarray:
        values = np.asarray(positions)[..., self.axis]
        return values <= self.threshold if self.below else values >= self.threshold


class PlaneTask(Task):
    """Planar forces up to 1 N, durations up to 0.1 s; captured: x <= 0; successful: y >= 0.02."""

    name = "plane-test"

    def __init__(self, accept: Callable[[np.ndarray, np.ndarray], bool] | None = None) -> None:
        super().__init__(TaskConfig(timestep=0.01, likelihood_lambda=50.0, max_duration=0.1))
        self.accept = accept or (lambda pos, vel: True)
        self.bounds_checks = 0

    def build_scene(self, n_objects: int, friction: float, drive: np.ndarray | None = None) -> Scene:
        objects = tuple(RigidObject(f"p{i}", Geom("sphere", (0.01,)), 0.5) for i in range(n_objects))
        return Scene(objects=objects, robot=None, statics=(), friction=friction, timestep=0.01)

    def sample_trajectory(self, rng: np.random.Generator, n_objects: int) -> Trajectory:
        return Trajectory(initial=_point_frame(n_objects), friction=0.0, drive=np.zeros(0))

    def robot_force(self, state: RobotState, rng: np.random.Generator | None = None) -> np.ndarray:
        return np.zeros(0)

    def capture_region(self, root: FrameState) -> HalfSpace:
        return HalfSpace(0, 0.0, below=True)

    def success_region(self) -> HalfSpace:
        return HalfSpace(1, 0.02, below=False)

    def wrench_limits(self, scene: Scene) -> WrenchLimits:
        limits = np.zeros((scene.n_objects, 6))
        limits[:, :2] = 1.0
        return WrenchLimits(max_wrench=limits, max_duration=self.config.max_duration)

    def _state_box(self) -> StateBox:
        return StateBox(low=(-10.0,) * 3, high=(10.0,) * 3, max_speed=100.0)

    def within_bounds(self, object_pos: np.ndarray, object_vel: np.ndarray) -> bool:
        self.bounds_checks += 1
        return bool(self.accept(object_pos, object_vel))


def _point_frame(n_objects: int) -> FrameState:
    pos = np.zeros((n_objects, 3))
    pos[:, 0] = np.arange(n_objects)
    return FrameState(pos, np.tile([1.0, 0, 0, 0], (n_objects, 1)), np.zeros((n_objects, 6)), np.zeros(0), np.zeros(0))


def _grow_fake(
    task: PlaneTask, budget: TreeBudget, seed: int = 0, n_objects: int = 2, cost: CostModel | None = None
) -> tuple[CostField, PointMassSimulator]:
    simulator = PointMassSimulator(task.build_scene(n_objects, 0.0))
    assert isinstance(simulator, Simulator)
    field = grow_tree(
        simulator,
        task,
        _point_frame(n_objects),
        np.zeros(0),
        np.random.default_rng(seed),
        budget=budget,
        cost_model=cost or WrenchWorkCost(),
    )
    return field, simulator


def _check_tree_invariants(field: CostField, max_step: float) -> None:
    assert field.costs[0] == 0.0
    assert field.parents[0] == -1
    assert field.times[0] == 0.0
    children = np.arange(1, field.nodes)
    parents = field.parents[1:]
    assert np.all(parents >= 0)
    assert np.all(parents < children)  # a parent is always an earlier node
    assert np.all(field.costs >= 0)
    assert np.all(field.costs[1:] >= field.costs[parents] + MIN_COST * 0.5)
    steps = field.times[1:] - field.times[parents]
    assert np.all(steps > 0)
    assert np.all(steps <= max_step + 1e-12)
    assert field.object_pos.shape[0] == field.times.shape[0] == field.nodes


# ---------------------------------------------------------------- EST logic with physics faked


def test_rejecting_everything_leaves_the_root_alone() -> None:
    task = PlaneTask(accept=lambda pos, vel: False)
    field, simulator = _grow_fake(task, TreeBudget(expansions=25))
    assert field.nodes == 1
    assert field.expansions == 25
    np.testing.assert_array_equal(field.costs, [0.0])
    np.testing.assert_array_equal(field.object_pos[0], _point_frame(2).object_pos)
    # Every iteration still propagated (and was checked) before being rejected.
    assert len(simulator.propagations) == 25
    assert task.bounds_checks == 25
    assert simulator.resets == 1


def test_child_costs_are_the_work_of_the_sampled_wrenches() -> None:
    task = PlaneTask()
    field, simulator = _grow_fake(task, TreeBudget(expansions=40))
    assert field.nodes == 41
    assert field.expansions == 40
    _check_tree_invariants(field, max_step=0.1)
    assert len(simulator.propagations) == 40
    for child, record in enumerate(simulator.propagations, start=1):
        parent = field.parents[child]
        wrench, before, after = record.wrench, record.before, record.after
        # Propagation started from the parent's restored state and ended at the child.
        np.testing.assert_array_equal(before, field.object_pos[parent])
        np.testing.assert_array_equal(after, field.object_pos[child])
        # Wrenches stay within the task's limits: planar forces <= 1 N, nothing else.
        assert np.all(np.abs(wrench[:, :2]) <= 1.0)
        np.testing.assert_array_equal(wrench[:, 2:], 0.0)
        work = np.abs(np.sum(wrench[:, :3] * (after - before), axis=1)).sum()
        assert field.costs[child] - field.costs[parent] == pytest.approx(max(work, MIN_COST), rel=1e-9, abs=1e-15)
        assert field.times[child] - field.times[parent] == pytest.approx(record.steps * 0.01)
    # Durations follow t_max U^(1/d) with d = 4 perturbed components: long ones dominate.
    steps = np.array([record.steps for record in simulator.propagations])
    assert steps.min() >= 1
    assert steps.max() <= 10
    assert np.median(steps) >= 6


class _OneAtATimeCost:
    """A cost model of one's own without ``increments``: the tree calls it once per node."""

    name = "one-at-a-time"
    needs_friction_work = False

    def __init__(self) -> None:
        self.calls = 0

    def __call__(self, propagation: Propagation) -> float:
        self.calls += 1
        return WrenchWorkCost()(propagation)


def test_a_cost_model_without_increments_is_called_once_per_node() -> None:
    own = _OneAtATimeCost()
    field, _ = _grow_fake(PlaneTask(), TreeBudget(expansions=40), cost=own)  # type: ignore[arg-type]
    reference, _ = _grow_fake(PlaneTask(), TreeBudget(expansions=40))
    assert own.calls == field.nodes - 1 == 40
    assert field.costs.tolist() == reference.costs.tolist()


def test_rejected_states_never_enter_the_tree() -> None:
    task = PlaneTask(accept=lambda pos, vel: bool(np.all(pos[:, 1] <= 0.002)))
    field, simulator = _grow_fake(task, TreeBudget(expansions=60))
    assert 1 < field.nodes < 61
    assert field.expansions == 60
    assert np.all(field.object_pos[:, :, 1] <= 0.002)
    rejected = [r for r in simulator.propagations if np.any(r.after[:, 1] > 0.002)]
    assert len(rejected) == 60 - (field.nodes - 1)


def test_node_budget_counts_accepted_children() -> None:
    calls = {"n": 0}

    def every_other(pos: np.ndarray, vel: np.ndarray) -> bool:
        calls["n"] += 1
        return calls["n"] % 2 == 0

    field, _ = _grow_fake(PlaneTask(accept=every_other), TreeBudget(expansions=None, nodes=5))
    assert field.nodes == 6
    assert field.expansions == 10
    both, _ = _grow_fake(PlaneTask(), TreeBudget(expansions=4, nodes=50))
    assert (both.nodes, both.expansions) == (5, 4)


def test_fake_tree_is_a_fixed_function_of_the_seed() -> None:
    first, _ = _grow_fake(PlaneTask(), TreeBudget(expansions=30), seed=11)
    again, _ = _grow_fake(PlaneTask(), TreeBudget(expansions=30), seed=11)
    other, _ = _grow_fake(PlaneTask(), TreeBudget(expansions=30), seed=12)
    for name in ("costs", "object_pos", "parents", "times"):
        assert np.array_equal(getattr(first, name), getattr(again, name))
    assert not np.array_equal(first.costs, other.costs)


def test_algorithm_1_scores_with_physics_faked() -> None:
    task = PlaneTask()
    frame = _point_frame(1)
    simulator = PointMassSimulator(task.build_scene(1, 0.0))
    config = AnalyzerConfig(expansions=50)
    scores, field = analyze_frame(
        task, frame, friction=0.0, drive=np.zeros(0), seed=3, config=config, simulator=simulator
    )
    captured = field.object_pos[:, 0, 0] <= 0.0
    successful = field.object_pos[:, 0, 1] >= 0.02
    assert 0 < captured.sum() < field.nodes  # the tree spreads to both sides
    assert scores.capture_score == pytest.approx(region_score(field.costs, captured, 50.0))
    assert scores.success_score == pytest.approx(region_score(field.costs, successful, 50.0))
    assert (scores.nodes, scores.expansions) == (51, 50)
    # With lambda = 0 the likelihood is uniform: the scores are the fractions of nodes.
    uniform = score_field(task, frame, field, 0.0)
    assert uniform == pytest.approx((captured.mean(), successful.mean()))
    assert score_field(task, frame, field, 50.0) == pytest.approx((scores.capture_score, scores.success_score))


# ---------------------------------------------------------------- EST over MuJoCo


PushingFrame = tuple[PushingTask, FrameState, float, np.ndarray]


@pytest.fixture(scope="module")
def pushing_frame() -> PushingFrame:
    task = PushingTask()
    trajectory = task.sample_trajectory(np.random.default_rng(7), 2)
    return task, trajectory.initial, trajectory.friction, trajectory.drive


def _grow_mujoco(
    pushing_frame: PushingFrame, budget: TreeBudget, seed: int, cost: CostModel | None = None
) -> CostField:
    task, frame, friction, drive = pushing_frame
    simulator = MujocoSimulator(task.build_scene(frame.n_objects, friction))
    return grow_tree(
        simulator, task, frame, drive, np.random.default_rng(seed), budget=budget, cost_model=cost or WrenchWorkCost()
    )


@pytest.mark.parametrize("budget", [1, 20, 45])
def test_iteration_budget(pushing_frame: PushingFrame, budget: int) -> None:
    field = _grow_mujoco(pushing_frame, TreeBudget(expansions=budget), seed=0)
    assert field.expansions == budget
    assert field.nodes <= budget + 1
    assert field.nodes > 1
    _check_tree_invariants(field, max_step=0.1)
    np.testing.assert_array_equal(field.object_pos[0], pushing_frame[1].object_pos)
    assert field.total_s >= field.physics_s > 0


def test_node_budget(pushing_frame: PushingFrame) -> None:
    field = _grow_mujoco(pushing_frame, TreeBudget(expansions=None, nodes=15), seed=1)
    assert field.nodes == 16
    assert field.expansions >= 15


def test_zero_budget_gives_the_root_only(pushing_frame: PushingFrame) -> None:
    field = _grow_mujoco(pushing_frame, TreeBudget(expansions=0), seed=1)
    assert (field.nodes, field.expansions) == (1, 0)


def test_same_seed_same_field_different_seed_different_field(pushing_frame: PushingFrame) -> None:
    first = _grow_mujoco(pushing_frame, TreeBudget(expansions=30), seed=5)
    again = _grow_mujoco(pushing_frame, TreeBudget(expansions=30), seed=5)
    other = _grow_mujoco(pushing_frame, TreeBudget(expansions=30), seed=6)
    for name in ("costs", "object_pos", "parents", "times"):
        assert np.array_equal(getattr(first, name), getattr(again, name))
    assert first.expansions == again.expansions
    assert not np.array_equal(first.costs, other.costs)
    assert not np.array_equal(first.object_pos, other.object_pos)


def test_energy_cost_model_tree(pushing_frame: PushingFrame) -> None:
    field = _grow_mujoco(pushing_frame, TreeBudget(expansions=30), seed=2, cost=EnergyBalanceCost())
    assert field.expansions == 30
    _check_tree_invariants(field, max_step=0.1)
    wrench = _grow_mujoco(pushing_frame, TreeBudget(expansions=30), seed=2)
    # Same random stream, same propagations: only the costs differ.
    np.testing.assert_array_equal(field.object_pos, wrench.object_pos)
    assert not np.array_equal(field.costs, wrench.costs)


# ---------------------------------------------------------------- budget object


def test_tree_budget_validation_and_capacity() -> None:
    assert TreeBudget().expansions == 300
    assert TreeBudget(expansions=10).node_capacity == 11
    assert TreeBudget(expansions=10, nodes=3).node_capacity == 4
    assert TreeBudget(expansions=3, nodes=10).node_capacity == 4
    assert TreeBudget(expansions=None, nodes=7).expansion_limit == 100_000
    with pytest.raises(InvalidParameterError, match="give expansions, nodes or both"):
        TreeBudget(expansions=None, nodes=None)
    with pytest.raises(InvalidParameterError, match="expansions must be a non-negative integer"):
        TreeBudget(expansions=-5)
    with pytest.raises(InvalidParameterError, match="nodes must be a non-negative integer"):
        TreeBudget(expansions=5, nodes=2.5)
