"""The controller's costs differ as documented: task, heuristic, margin, learned."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pytest

from energy_margin.control.costs import (
    COSTS,
    CostContext,
    CostWeights,
    Predictions,
    get_cost,
    heuristic_cost,
    holding_task,
    learned_cost,
    margin_cost,
    task_cost,
)
from energy_margin.errors import EnergyMarginError
from energy_margin.tasks import RobotState, Task, get_task
from energy_margin.world.state import FrameState


def _predictions(object_xy: list[tuple[float, float]]) -> Predictions:
    """One object, one period per sample, the pusher at rest at (1.0, 1.3)."""
    k = len(object_xy)
    pos = np.zeros((k, 1, 1, 3))
    pos[:, 0, 0, :2] = object_xy
    quat = np.zeros((k, 1, 1, 4))
    quat[..., 0] = 1.0
    robot_q = np.tile([1.0, 1.3, 0.0, 0.0], (k, 1, 1))
    return Predictions(
        object_pos=pos,
        object_quat=quat,
        object_vel=np.zeros((k, 1, 1, 6)),
        robot_q=robot_q,
        robot_v=np.zeros((k, 1, 4)),
        commands=np.zeros((k, 1, 3)),
        forces=np.tile([0.0, 5.0, 0.0, 0.0], (k, 1)),
        targets=None,
        end_time=0.5,
    )


def _context(**options: object) -> CostContext:
    values: dict[str, object] = {
        "length_scale": 0.1,
        "weights": CostWeights(),
        "friction": 0.2,
        "drive": np.array([0.0, 5.0]),
        "analysis_drive": lambda force: np.asarray(force)[:2],
        "margin_expansions": 5,
        "margin_samples": 1,
        "seed_sequence": np.random.SeedSequence(0),
    }
    values.update(options)
    return CostContext(get_task("pushing"), **values)  # type: ignore[arg-type]


def test_task_cost_is_the_distance_to_the_success_band_in_length_scales() -> None:
    # The band along the wall: y in [1.45, 1.65] for the default wall and radius.
    costs = task_cost(_predictions([(1.0, 1.5), (1.0, 1.0)]), _context())
    assert costs[0] == pytest.approx(0.0)
    assert costs[1] == pytest.approx((1.0 + 0.25) * 0.45 / 0.1)


def test_task_cost_charges_departures_from_the_script_and_leaving_the_bounds() -> None:
    predictions = _predictions([(1.0, 1.5), (1.0, 1.5), (2.5, 1.5)])
    commands = predictions.commands.copy()
    commands[1] = 0.5
    moved = Predictions(**{**predictions.__dict__, "commands": commands})
    costs = task_cost(moved, _context())
    assert costs[1] == pytest.approx(0.05 * 0.25)
    # x = 2.5 m lies outside the workspace (-0.1, 2.1): the bounds penalty.
    assert costs[2] >= 100.0


def test_heuristic_adds_the_distance_outside_the_capture_region() -> None:
    # Pusher at rest: the capture region is the 0.6 m disc around it.
    predictions = _predictions([(1.0, 1.5), (1.8, 1.0)])
    context = _context()
    task = task_cost(predictions, context)
    heuristic = heuristic_cost(predictions, context)
    assert heuristic[0] == pytest.approx(task[0])
    outside = np.hypot(0.8, 0.3) - 0.6
    assert heuristic[1] == pytest.approx(task[1] + outside / 0.1)


def test_margin_subtracts_analysed_scores_and_gives_the_rest_the_lowest() -> None:
    predictions = _predictions([(1.0, 1.5), (1.0, 1.0), (1.2, 1.4)])
    context = _context(margin_samples=2)
    task = task_cost(predictions, context)
    margin = margin_cost(predictions, context)
    assert context.analyses == 2
    bonus = (task - margin) / 2.0
    assert np.all(bonus >= 0.0) and np.all(bonus <= 2.0)
    # The sample with the highest task cost was not analysed: it takes the lowest analysed score.
    assert bonus[1] == pytest.approx(min(bonus[0], bonus[2]))
    # The same seeds give the same scores.
    again = margin_cost(predictions, _context(margin_samples=2))
    np.testing.assert_array_equal(margin, again)


class _FixedMargin:
    task_name = "pushing"

    def predict(self, task: Task, frames: Sequence[FrameState]) -> tuple[np.ndarray, np.ndarray]:
        assert len(frames) == 2 and frames[0].object_pos.shape == (1, 3)
        return np.array([0.5, 1.0]), np.array([0.0, 0.25])


def test_learned_subtracts_the_model_scores_of_every_end_state() -> None:
    predictions = _predictions([(1.0, 1.5), (1.0, 1.0)])
    context = _context(model=_FixedMargin())
    np.testing.assert_allclose(
        learned_cost(predictions, context), task_cost(predictions, context) - 2.0 * np.array([0.5, 1.25])
    )
    with pytest.raises(EnergyMarginError, match="needs a model"):
        learned_cost(predictions, _context())


def test_holding_task_holds_the_command_and_leaves_the_task_alone() -> None:
    task = get_task("scooping")
    held = holding_task(task, np.zeros(5), np.full(5, 0.01))
    np.testing.assert_array_equal(held.robot_targets(RobotState(np.ones(1), 1.5, np.zeros(5), np.zeros(5)), None), 0.01)
    scripted = task.robot_targets(RobotState(np.ones(1), 1.5, np.zeros(5), np.zeros(5)), None)
    assert not np.allclose(scripted, 0.01)


def test_cost_registry() -> None:
    assert set(COSTS) == {"task", "heuristic", "margin", "learned"}
    with pytest.raises(EnergyMarginError, match="unknown cost 'fast'"):
        get_cost("fast")
