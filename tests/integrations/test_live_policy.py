"""A live score's success continued under the user's policy (integrations/live_policy.py)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from energy_margin.analysis.continuation import continued_success, controlled_success
from energy_margin.analysis.frame import AnalyzerConfig, analyze_frame
from energy_margin.errors import EnergyMarginError, InvalidParameterError
from energy_margin.integrations.live_model import LiveModelScorer, LiveOptions
from energy_margin.sim.base import ModelCommand
from tiny_scene import ARM_OVER_PUCK

#: The puck has left where it starts (8 cm in the plane): only an arm sweeping through it does that.
PUSHED = {"type": "not", "region": {"type": "box", "center": [0.2, 0.1, 0.03], "half_size": [0.08, 0.08, 1.0]}}


def _scorer(**kwargs: object) -> tuple[LiveModelScorer, mujoco.MjData]:
    model = mujoco.MjModel.from_xml_string(ARM_OVER_PUCK)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    options = LiveOptions(budget_s=None, max_expansions=20, seed=3, continuation=4, horizon_s=1.5)
    scorer = LiveModelScorer(model, objects="puck", capture={"type": "distance", "site": "tip", "max": 0.5},
                             success=PUSHED, options=options, **kwargs)  # type: ignore[arg-type]  # fmt: skip
    return scorer, data


class Sweep:
    """Drives the arm's servo to 1.2 rad, through the puck; counts its calls."""

    def __init__(self) -> None:
        self.calls = 0

    def __call__(self, data: mujoco.MjData) -> np.ndarray:
        self.calls += 1
        return np.array([1.2])


def test_a_policy_that_sweeps_the_puck_away_scores_the_success_the_held_command_misses() -> None:
    held, data = _scorer()
    assert held.score(data)["success_score"] == 0.0  # the servo holds 0 rad: the puck stays
    policy = Sweep()
    swept, _ = _scorer(policy=policy)
    first = swept.score(data)
    assert first["success_score"] == 1.0 and first["continuation_ms"] > 0.0
    assert first["capture_score"] == held.score(data)["capture_score"]  # the tree is the same
    # Each continuation ran a copy: the policy driving the robot was never called.
    assert policy.calls == 0
    again, _ = _scorer(policy=Sweep())
    assert again.score(data) | {"ms": 0, "continuation_ms": 0} == first | {"ms": 0, "continuation_ms": 0}


def test_a_policy_holding_the_command_continues_as_the_held_command_does() -> None:
    """Under a controller that sets the held command, the draws and their ends are continued_success's."""
    scorer, data = _scorer()
    frame = scorer.frame(data)
    scorer.task.held = ModelCommand(ctrl=np.array([0.6]), mocap_pos=None, mocap_quat=None)
    config = AnalyzerConfig(expansions=20, continuation=0)
    drive = scorer.drive
    _, field = analyze_frame(scorer.task, frame, friction=scorer.friction, drive=drive, seed=5, config=config,
                             simulator=scorer.simulator)  # fmt: skip
    lam = scorer.task.config.likelihood_lambda
    duration = scorer.task.config.duration
    plain = continued_success(scorer.simulator, scorer.task, frame, field, drive, lam=lam, samples=6, seed=5)

    def controllers():  # type: ignore[no-untyped-def]
        return lambda simulator: simulator.set_model_command(scorer.task.held)

    controlled = controlled_success(scorer.simulator, scorer.task, frame, field, controllers, lam=lam, samples=6,
                                    seed=5, horizon=duration, period=0.01)  # fmt: skip
    assert controlled == plain


def test_a_policy_s_controls_of_the_wrong_shape_are_refused_in_one_line() -> None:
    scorer, data = _scorer(policy=lambda data: np.zeros(3))
    with pytest.raises(EnergyMarginError, match=r"^the policy returned controls of shape \(3,\); the model has 1 "):
        scorer.score(data)
    with pytest.raises(EnergyMarginError, match=r"^policy must be callable"):
        _scorer(policy="sweep")


def test_no_continuation_runs_once_the_episode_is_over() -> None:
    held, data = _scorer()
    swept, _ = _scorer(policy=Sweep())
    over = swept.score(data, horizon_s=0.0)
    assert over["continuation_ms"] == 0.0 and over["success_score"] == held.score(data)["success_score"]


def test_a_continuation_needs_a_positive_period_and_horizon() -> None:
    with pytest.raises(InvalidParameterError, match=r"^policy_period_s must be a finite number > 0"):
        _scorer(policy=Sweep(), policy_period_s=0.0)
    with pytest.raises(InvalidParameterError, match=r"^horizon_s must be a finite number > 0"):
        LiveModelScorer(mujoco.MjModel.from_xml_string(ARM_OVER_PUCK), objects="puck", capture=PUSHED,
                        success=PUSHED, options=LiveOptions(horizon_s=-1.0))  # fmt: skip


def test_a_policy_is_refused_beside_a_held_or_coasting_robot() -> None:
    """Still and coasting robots carry a heavy armature: a policy's torques would not move them."""
    model = mujoco.MjModel.from_xml_string(ARM_OVER_PUCK)
    for hold in ("still", "coasting"):
        with pytest.raises(EnergyMarginError, match=rf"^a policy drives the robot through .*'{hold}'"):
            LiveModelScorer(model, objects="puck", capture=PUSHED, success=PUSHED, policy=Sweep(),
                            options=LiveOptions(hold=hold))  # type: ignore[arg-type]  # fmt: skip
