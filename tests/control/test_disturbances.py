"""Disturbance levels: the plant's friction, pushes and observation noise."""

from __future__ import annotations

import numpy as np
import pytest

from energy_margin.control.disturbances import DISTURBANCES, draw_plant, get_disturbance, observe, push_wrenches
from energy_margin.errors import EnergyMarginError


def test_none_is_the_nominal_plant() -> None:
    level = get_disturbance("none")
    rng = np.random.default_rng(0)
    friction, pushes = draw_plant(level, rng, nominal_friction=0.2, duration=2.0, masses=np.ones(3))
    assert friction == 0.2 and pushes == []
    positions = np.arange(9.0).reshape(3, 3)
    np.testing.assert_array_equal(observe(positions, level, rng), positions)


def test_hard_draws_friction_in_its_range_and_pushes_at_its_rate() -> None:
    level = DISTURBANCES["hard"]
    frictions, counts = [], []
    for seed in range(400):
        friction, pushes = draw_plant(
            level, np.random.default_rng(seed), nominal_friction=0.2, duration=2.0, masses=np.full(4, 0.2)
        )
        frictions.append(friction)
        counts.append(len(pushes))
        for push in pushes:
            assert 0 <= push.start < 2.0 and 0 <= push.target < 4
            # The force held for the push's duration changes the object's speed by push_speed.
            assert np.linalg.norm(push.force) * push.duration / 0.2 == pytest.approx(level.push_speed)
    assert min(frictions) >= 0.2 / level.friction_scale and max(frictions) <= 0.2 * level.friction_scale
    assert min(frictions) < 0.2 / 2 and max(frictions) > 0.2 * 2
    assert np.mean(counts) == pytest.approx(level.push_rate * 2.0, rel=0.15)


def test_push_wrenches_are_active_only_during_the_push() -> None:
    level = DISTURBANCES["hard"]
    for seed in range(50):
        _, pushes = draw_plant(
            level, np.random.default_rng(seed), nominal_friction=0.2, duration=2.0, masses=np.ones(2)
        )
        if pushes:
            break
    push = pushes[0]
    during = push_wrenches(pushes[:1], push.start + 0.5 * push.duration, 2)
    np.testing.assert_allclose(during[push.target, :2], push.force)
    assert not push_wrenches(pushes[:1], push.start + push.duration, 2).any()


def test_observation_noise_has_the_level_standard_deviation() -> None:
    level = DISTURBANCES["hard"]
    positions = np.zeros((20000, 3))
    noisy = observe(positions, level, np.random.default_rng(0))
    assert np.std(noisy[:, :2]) == pytest.approx(level.position_noise, rel=0.05)
    assert not noisy[:, 2].any()


def test_unknown_level_is_one_clear_error() -> None:
    with pytest.raises(EnergyMarginError, match="unknown disturbance 'storm'"):
        get_disturbance("storm")
