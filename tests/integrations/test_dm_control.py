"""The dm_control wrapper on dm_control's own manipulation task (the Kinova Jaco lifting a Duplo brick)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("dm_control")

from energy_margin.errors import EnergyMarginError
from energy_margin.integrations.dm_control import (
    MarginEnvironment,
    PhysicsScorer,
    align_dm_control_index,
    episode_steps,
    physics_handles,
)
from energy_margin.integrations.live_model import INFO_KEYS

CAPTURE = {"type": "distance", "site": "jaco_arm/jaco_hand/pinchsite", "max": 0.15}
SUCCESS = {"type": "height", "min": 0.1}


def lift_brick(seed: int = 0):  # type: ignore[no-untyped-def]
    from dm_control import manipulation

    return manipulation.load("lift_brick_features", seed=seed)


def short_lift_brick(time_limit: float, seed: int):  # type: ignore[no-untyped-def]
    """The Jaco lifting a brick, in composer episodes of ``time_limit`` seconds (0.04 s control steps)."""
    from dm_control import composer
    from dm_control.manipulation.shared import registry

    return composer.Environment(
        registry.get_constructor("lift_brick_features")(), time_limit=time_limit, random_state=seed
    )


def steps(env, n: int) -> list[np.ndarray]:  # type: ignore[no-untyped-def]
    spec = env.action_spec()
    rng = np.random.default_rng(0)
    return [rng.uniform(spec.minimum, spec.maximum) for _ in range(n)]


def test_the_index_tables_hold_only_fields_this_mujoco_has() -> None:
    assert align_dm_control_index() == []  # already aligned on import
    env = lift_brick()
    model, _data = physics_handles(env.physics)
    assert model.nq == env.physics.model.nq


def test_observations_are_identical_with_and_without_the_wrapper() -> None:
    plain, wrapped_env = lift_brick(3), lift_brick(3)
    wrapper = MarginEnvironment(
        wrapped_env, objects="duplo2x4/", capture=CAPTURE, success=SUCCESS, budget_s=None, max_expansions=10, every=2
    )
    first, second = plain.reset(), wrapper.reset()
    assert wrapper.margin is not None and set(wrapper.margin) == set(INFO_KEYS)
    for name, value in first.observation.items():
        assert np.array_equal(value, second.observation[name])
    for action in steps(plain, 6):
        a, b = plain.step(action), wrapper.step(action)
        assert a.reward == b.reward
        for name, value in a.observation.items():
            assert np.array_equal(value, b.observation[name]), name
    assert len(wrapper.margins) == 1 + 3
    assert wrapper.action_spec() == plain.action_spec()


def test_physics_scorer_and_recording(tmp_path: Path) -> None:
    env = lift_brick()
    env.reset()
    scorer = PhysicsScorer(env, objects="duplo2x4/", capture=CAPTURE, success=SUCCESS, options=None)
    margin = scorer.score_physics()
    assert 0.0 <= margin["capture_score"] <= 1.0
    assert scorer.labels(physics_handles(env)[1]) == (False, False)
    wrapper = MarginEnvironment(env, objects="duplo2x4/", capture=CAPTURE, success=SUCCESS, every=0, record=True)
    wrapper.reset()
    for action in steps(env, 4):
        wrapper.step(action)
    rows = np.load(wrapper.save_episode(tmp_path / "episode.npz"))
    assert rows["qpos"].shape == (5, env.physics.model.nq)
    assert wrapper.margins == []


def test_bad_inputs_are_one_line() -> None:
    with pytest.raises(EnergyMarginError, match="object has no MuJoCo model"):
        MarginEnvironment(object(), objects="x", capture=CAPTURE, success=SUCCESS)
    with pytest.raises(EnergyMarginError, match="has no MuJoCo model"):
        PhysicsScorer(object(), objects="x", capture=CAPTURE, success=SUCCESS)
    with pytest.raises(EnergyMarginError, match=r"objects.bodies: no body 'brick'"):
        MarginEnvironment(lift_brick(), objects="brick", capture=CAPTURE, success=SUCCESS)


def test_a_calibration_adds_the_alarm() -> None:
    from energy_margin.evaluation.monitor import MonitorCalibration

    always = MonitorCalibration(
        threshold=2.0,
        alpha=0.1,
        rank=1,
        n_successes=9,
        n_trajectories=9,
        scorer="margin",
        score="success",
        start_frame=1,
    )
    wrapper = MarginEnvironment(
        lift_brick(3),
        objects="duplo2x4/",
        capture=CAPTURE,
        success=SUCCESS,
        budget_s=None,
        max_expansions=3,
        calibration=always,
    )
    wrapper.reset()
    for action in steps(wrapper, 2):
        wrapper.step(action)
    assert [margin["alarm"] for margin in wrapper.margins] == [False, True, True]  # call 0 is not monitored


class CountedPolicy:
    """Holds the physics' controls where they are; every copy counts its calls in one shared list."""

    def __init__(self, calls: list[int]) -> None:
        self.calls = calls
        self.index = -1

    def __deepcopy__(self, memo: dict) -> CountedPolicy:  # type: ignore[type-arg]
        copy = CountedPolicy(self.calls)
        copy.index = len(self.calls)
        self.calls.append(0)
        return copy

    def __call__(self, data) -> np.ndarray:  # type: ignore[no-untyped-def]
        self.calls[self.index] += 1
        return np.array(data.ctrl)


def test_a_policy_continues_the_success_score_to_the_end_of_the_episode() -> None:
    """Composer's 0.4 s episode of 0.04 s control steps: each copy commands every step left, one per step."""

    def episode():  # type: ignore[no-untyped-def]
        return short_lift_brick(0.4, 3)

    calls: list[int] = []
    policy = CountedPolicy(calls)
    wrapper = MarginEnvironment(episode(), objects="duplo2x4/", capture=CAPTURE, success=SUCCESS, budget_s=None,
                                max_expansions=5, policy=policy, continuation=3)  # fmt: skip
    plain = episode()
    assert (wrapper.session.step_s, wrapper.session.episode_steps) == (pytest.approx(0.04), 10)
    first, reference = wrapper.reset(), plain.reset()
    # Each copy commands every 0.04 s from its node (up to a few steps past the scored state) to the episode's end.
    per_call = [calls[:]]
    assert wrapper.margin is not None and wrapper.margin["continuation_ms"] > 0.0
    for action in steps(plain, 6):
        before = len(calls)
        a, b = plain.step(action), wrapper.step(action)
        per_call.append(calls[before:])
        assert a.reward == b.reward and all(np.array_equal(v, b.observation[k]) for k, v in a.observation.items())
    for done, copies in enumerate(per_call):
        left = 10 - done
        assert 1 <= len(copies) <= 3 and min(copies) >= 1 and left - 3 <= max(copies) <= left, (done, copies)
    assert policy.index == -1  # the policy driving the robot was never called, only its copies
    assert set(first.observation) == set(reference.observation)


def test_episode_steps_of_either_kind_of_time_limit() -> None:
    from dm_control import suite

    assert episode_steps(suite.load("cartpole", "balance"), 0.01) == 1000  # control: counted in steps
    assert episode_steps(lift_brick(), 0.04) == 250  # composer: 10 s of physics time
    assert episode_steps(object(), 0.04) is None


def test_a_step_after_the_last_starts_a_new_scored_episode() -> None:
    """dm_env resets by itself on the step after ``LAST``; composer rebuilds its physics there."""
    env = short_lift_brick(0.2, 3)
    wrapper = MarginEnvironment(env, objects="duplo2x4/", capture=CAPTURE, success=SUCCESS, budget_s=None,
                                max_expansions=3)  # fmt: skip
    wrapper.reset()
    actions = steps(env, 7)
    for action in actions[:5]:
        time_step = wrapper.step(action)
    assert time_step.last() and len(wrapper.margins) == 6 == 1 + wrapper.session.episode_steps  # type: ignore[operator]
    assert wrapper.step(actions[5]).first()
    assert len(wrapper.margins) == 1 and wrapper.session.steps == 0
    assert wrapper._data is physics_handles(env)[1]  # the rebuilt physics' data, not the last episode's
    wrapper.step(actions[6])
    assert len(wrapper.margins) == 2 and wrapper.session.steps == 1


def test_episode_steps_is_where_the_episode_ends() -> None:
    from dm_control.suite import cartpole

    for limit in (0.4, 1.0):
        env = short_lift_brick(limit, 0)
        env.reset()
        count, action = 0, np.zeros(env.action_spec().shape)
        while not env.step(action).last():
            count += 1
        assert count + 1 == episode_steps(env, env.control_timestep())
    control = cartpole.balance(time_limit=0.5)
    control.reset()
    count = 1
    while not control.step(np.zeros(1)).last():
        count += 1
    assert count == episode_steps(control, control.control_timestep())
