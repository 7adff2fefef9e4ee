from __future__ import annotations

import numpy as np
import pytest
from tests.planning.test_est import PlaneTask, PointMassSimulator, _check_tree_invariants, _point_frame

from energy_margin.analysis.frame import AnalyzerConfig, analyze_frame
from energy_margin.errors import InvalidParameterError
from energy_margin.planning import TreeBudget, grow_tree
from energy_margin.planning.costs import EnergyBalanceCost, WrenchWorkCost
from energy_margin.planning.methods import MonteCarloExpansion, RrtExpansion, expansion_factory
from energy_margin.sim.mujoco_backend import MujocoSimulator
from energy_margin.tasks import PushingTask, ScoopingTask


def _grow(method: str, expansions: int, *, seed: int = 0, task: PlaneTask | None = None, **options: object):
    task = task or PlaneTask()
    simulator = PointMassSimulator(task.build_scene(2, 0.0))
    field = grow_tree(
        simulator,
        task,
        _point_frame(2),
        np.zeros(0),
        np.random.default_rng(seed),
        budget=TreeBudget(expansions=expansions),
        cost_model=WrenchWorkCost(),
        method=method,
        **options,  # type: ignore[arg-type]
    )
    return field, simulator


@pytest.mark.parametrize("method", ["est", "montecarlo", "rrt"])
def test_every_method_gives_a_valid_cost_field(method: str) -> None:
    field, simulator = _grow(method, 57)
    assert field.expansions == 57
    assert len(simulator.propagations) == 57  # one propagation per iteration, whatever the method
    assert field.nodes == 58  # nothing is rejected in this world
    _check_tree_invariants(field, max_step=0.1)
    again, _ = _grow(method, 57)
    np.testing.assert_array_equal(field.costs, again.costs)
    np.testing.assert_array_equal(field.object_pos, again.object_pos)
    other, _ = _grow(method, 57, seed=1)
    assert not np.array_equal(field.costs, other.costs)


def test_methods_use_the_same_duration_distribution() -> None:
    steps = {method: [p.steps for p in _grow(method, 200)[1].propagations] for method in ("est", "montecarlo", "rrt")}
    means = [float(np.mean(v)) for v in steps.values()]
    assert max(means) - min(means) < 0.6  # 1..10 steps, biased to long: the same law for every method
    assert all(max(v) <= 10 and min(v) >= 1 for v in steps.values())


def test_montecarlo_chains_rollouts_from_the_root() -> None:
    field, simulator = _grow("montecarlo", 25, rollout_length=10)
    # ceil(25 / 10) = 3 roll-outs, taken layer by layer: 3 + 3 + ... = 25 propagations in all.
    assert len(simulator.propagations) == 25
    parents = field.parents
    assert list(parents[1:4]) == [0, 0, 0]  # the first layer starts every roll-out at the root
    assert list(parents[4:7]) == [1, 2, 3]  # the second continues each
    depth = np.zeros(field.nodes, dtype=int)
    for node in range(1, field.nodes):
        depth[node] = depth[parents[node]] + 1
    assert depth.max() == 9  # 25 = 3 * 8 + 1: one roll-out gets a ninth step
    assert np.bincount(depth)[1:].tolist() == [3] * 8 + [1]


def test_montecarlo_restarts_a_rejected_rollout() -> None:
    rollouts = MonteCarloExpansion(total=6, rollout_length=3)
    assert rollouts.n_rollouts == 2
    assert rollouts.parent(0, np.empty(0), 1) == 0
    assert rollouts.parent(1, np.empty(0), 1) == 0
    assert rollouts.parent(2, np.empty(0), 1) is None  # roll-out 0 still pending: the round ends
    rollouts.added(0, 1, 0, np.zeros(2))
    rollouts.rejected(1, 0)
    assert rollouts.parent(2, np.empty(0), 2) == 1
    assert rollouts.parent(3, np.empty(0), 2) == 0  # restarted at the root


def test_rrt_extends_the_node_nearest_to_the_target() -> None:
    rrt = RrtExpansion(dimension=2, capacity=10, extent=1.0)
    for node, point in enumerate([(0.0, 0.0), (0.5, 0.0), (0.0, -0.5)]):
        rrt.added(node - 1, node, max(node - 1, -1), np.array(point))
    # Uniforms map to [-extent, extent]: (0.9, 0.5) -> (0.8, 0.0), nearest (0.5, 0).
    assert rrt.parent(0, np.array([0.9, 0.5]), 3) == 1
    assert rrt.parent(1, np.array([0.5, 0.0]), 3) == 2  # (0, -1) -> (0, -0.5)
    assert rrt.parent(2, np.array([0.45, 0.55]), 3) == 0  # (-0.1, 0.1) -> the root
    np.testing.assert_allclose(rrt.target(np.array([0.0, 1.0])), [-1.0, 1.0])


def test_rrt_on_the_faked_world_extends_nearest_nodes() -> None:
    field, simulator = _grow("rrt", 30, rrt_extent=0.05)
    # Each propagation starts from the node its parent index names.
    for node in range(1, field.nodes):
        start = simulator.propagations[node - 1].before
        np.testing.assert_allclose(start, field.object_pos[field.parents[node]])


def test_unknown_method_and_bad_options() -> None:
    with pytest.raises(InvalidParameterError, match="method"):
        expansion_factory("prm", n_objects=1, total=1, capacity=2)
    with pytest.raises(InvalidParameterError, match="rollout_length"):
        MonteCarloExpansion(10, 0)
    with pytest.raises(InvalidParameterError, match="method"):
        AnalyzerConfig(method="prm")
    with pytest.raises(InvalidParameterError, match="batch"):
        AnalyzerConfig(batch=0)
    with pytest.raises(InvalidParameterError, match="friction"):
        AnalyzerConfig(batch=4, cost="energy")


# ------------------------------------------------------------------ batched expansion (MuJoCo)


def _pushing(n_objects: int = 3):
    task = PushingTask()
    trajectory = task.sample_trajectory(np.random.default_rng(3), n_objects)
    return task, trajectory


def _grow_batched(method: str, batch: int, threads: int, expansions: int = 40):
    task, trajectory = _pushing()
    simulator = MujocoSimulator(task.build_scene(3, trajectory.friction))
    return grow_tree(
        simulator,
        task,
        trajectory.initial,
        trajectory.drive,
        np.random.default_rng(5),
        budget=TreeBudget(expansions=expansions),
        cost_model=WrenchWorkCost(),
        method=method,
        batch=batch,
        threads=threads,
    )


@pytest.mark.parametrize("method", ["est", "montecarlo", "rrt"])
def test_batched_is_deterministic_and_independent_of_threads(method: str) -> None:
    first = _grow_batched(method, 8, 1)
    again = _grow_batched(method, 8, 1)
    two_threads = _grow_batched(method, 8, 2)
    for other in (again, two_threads):
        np.testing.assert_array_equal(first.costs, other.costs)
        np.testing.assert_array_equal(first.object_pos, other.object_pos)
        np.testing.assert_array_equal(first.parents, other.parents)
    assert first.expansions == 40
    _check_tree_invariants(first, max_step=0.1)


def test_batched_montecarlo_does_not_depend_on_the_batch_size() -> None:
    small, large = _grow_batched("montecarlo", 2, 1), _grow_batched("montecarlo", 16, 1)
    np.testing.assert_array_equal(small.costs, large.costs)
    np.testing.assert_array_equal(small.parents, large.parents)


def test_batch_one_is_the_reference_path() -> None:
    task, trajectory = _pushing()
    frame, drive = trajectory.initial, trajectory.drive
    kwargs = {"friction": trajectory.friction, "drive": drive, "seed": 11}
    reference, reference_field = analyze_frame(task, frame, config=AnalyzerConfig(expansions=30), **kwargs)
    explicit, explicit_field = analyze_frame(task, frame, config=AnalyzerConfig(expansions=30, batch=1), **kwargs)
    np.testing.assert_array_equal(reference_field.costs, explicit_field.costs)
    assert reference.capture_score == explicit.capture_score
    batched, batched_field = analyze_frame(task, frame, config=AnalyzerConfig(expansions=30, batch=8), **kwargs)
    # Rounds pick parents against the tree before the round: the tree differs, its size does not.
    assert batched_field.expansions == reference_field.expansions == 30
    assert not np.array_equal(batched_field.parents, reference_field.parents)
    assert 0.0 <= batched.capture_score <= 1.0


def test_batched_first_round_matches_one_at_a_time_physics() -> None:
    # Monte Carlo's first layer starts every roll-out at the root with the same controls in both
    # paths: the reached states agree up to the solver's warm start (zero in the batched path).
    one = _grow_batched("montecarlo", 1, 1, expansions=8)
    batched = _grow_batched("montecarlo", 8, 1, expansions=8)
    np.testing.assert_array_equal(one.parents, batched.parents)
    np.testing.assert_allclose(one.object_pos, batched.object_pos, atol=1e-6)
    np.testing.assert_allclose(one.costs, batched.costs, rtol=1e-4, atol=1e-9)


def test_batched_scooping_follows_the_script() -> None:
    task = ScoopingTask()
    trajectory = task.sample_trajectory(np.random.default_rng(0), 2)
    kwargs = {"friction": trajectory.friction, "drive": trajectory.drive, "seed": 2, "start_time": 1.2}
    _, one_field = analyze_frame(
        task, trajectory.initial, config=AnalyzerConfig(expansions=6, method="montecarlo"), **kwargs
    )
    _, batched_field = analyze_frame(
        task, trajectory.initial, config=AnalyzerConfig(expansions=6, method="montecarlo", batch=6), **kwargs
    )
    # One layer of six roll-outs from the root: same controls and servo targets in both paths.
    np.testing.assert_allclose(one_field.object_pos, batched_field.object_pos, atol=1e-5)


def test_batched_refuses_friction_work() -> None:
    task, trajectory = _pushing()
    simulator = MujocoSimulator(task.build_scene(3, trajectory.friction))
    with pytest.raises(InvalidParameterError, match="friction"):
        grow_tree(
            simulator,
            task,
            trajectory.initial,
            trajectory.drive,
            np.random.default_rng(0),
            budget=TreeBudget(expansions=4),
            cost_model=EnergyBalanceCost(),
            batch=2,
        )
