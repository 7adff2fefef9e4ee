"""Trees keep the robot's coordinates of every node: those of the node's own state, not its parent's."""

from __future__ import annotations

import numpy as np
import pytest

from energy_margin.analysis.frame import AnalyzerConfig, analyze_frame
from energy_margin.planning import tree as tree_module
from energy_margin.tasks import get_task


@pytest.mark.parametrize("batch", [1, 3])
def test_every_nodes_robot_coordinates_are_those_of_its_own_state(monkeypatch: pytest.MonkeyPatch, batch: int) -> None:
    task = get_task("pushing")
    trajectory = task.sample_trajectory(np.random.default_rng(4), 3)
    kept: dict[str, np.ndarray] = {}
    original = tree_module._Tree.field

    def field(self, expansions, physics_s, started):  # type: ignore[no-untyped-def]
        kept["states"] = self.states[: self.count].copy()
        return original(self, expansions, physics_s, started)

    monkeypatch.setattr(tree_module._Tree, "field", field)
    simulator = task.make_simulator(3, trajectory.friction, trajectory.drive)
    _, grown = analyze_frame(
        task,
        trajectory.initial,
        friction=trajectory.friction,
        drive=trajectory.drive,
        seed=2,
        config=AnalyzerConfig(expansions=30, batch=batch),
        simulator=simulator,
    )
    assert grown.robot_q is not None and grown.robot_q.shape[0] == grown.nodes > 5
    states = kept["states"]
    if batch > 1:
        # Batched states are the propagator's vectors: read their robot coordinates with it.
        propagator = simulator.rollout_propagator(1)  # type: ignore[attr-defined]
        expected = propagator.object_states(states)[3]
    else:
        expected = []
        for state in states:
            simulator.set_state(state)
            expected.append(simulator.robot_positions())
        expected = np.array(expected)
    np.testing.assert_array_equal(grown.robot_q, expected)
    # A child's coordinates differ from its parent's (the pusher moved on), so a parent's would not pass.
    children = np.flatnonzero(grown.parents >= 0)
    assert np.any(np.abs(grown.robot_q[children] - grown.robot_q[grown.parents[children]]) > 1e-6)
