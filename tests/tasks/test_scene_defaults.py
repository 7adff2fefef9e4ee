"""Perturbation settings derived from the scene when the file leaves them out (tasks/scene_defaults.py)."""

from __future__ import annotations

import numpy as np
import pytest

from energy_margin.cli import main
from energy_margin.errors import EnergyMarginError
from energy_margin.tasks.scene_defaults import (
    ANGULAR_RATIO,
    DEFAULTS,
    GRAVITY,
    LAMBDA_ENERGY,
    PROPAGATION_PER_FRAME,
    resolve_perturbation,
)
from energy_margin.tasks.scene_model import load_scene

SET_KEYS = """[perturbation]
linear_acceleration = [2.0, 2.0, 0.0]
angular_acceleration = [0.0, 0.0, 5.0]
max_duration = 0.1
"""


DERIVE = "[perturbation]\nderive = true\n"


def _derived_scene(make_scene, *, mass: str = "0.1", friction: str = "[0.3, 0.6]"):
    return make_scene(
        replace={SET_KEYS: DERIVE, "friction = [0.3, 0.6]": f"friction = {friction}"},
        model_replace={'mass="0.1"/></body>\n    <body name="box_b"': f'mass="{mass}"/></body>\n    <body name="box_b"'}
        if mass != "0.1"
        else None,
    )


def test_on_the_papers_cylinders_the_rule_gives_its_settings(make_scene) -> None:
    # The paper's pushing objects as free bodies: 0.2 kg cylinders, radius 5 cm, friction 0.1-0.3,
    # a 2 s motion (10 frames). Its 0.1 s, ~2 m/s^2 and 0.667 rad/s^2 about z come back; lambda is
    # 3.46, not 5, because a free body is perturbed along z too (the paper's task is planar).
    cylinder = '<geom type="cylinder" size="0.05 0.015" mass="0.2"/>'
    scene = make_scene(
        replace={
            SET_KEYS: DERIVE,
            "friction = [0.3, 0.6]": "friction = [0.1, 0.3]",
            "duration = 1.5": "duration = 2.0",
            "time = 1.5": "time = 2.0",
        },
        model_replace={'<geom type="box" size="0.03 0.03 0.03" mass="0.1"/>': cylinder},
    )
    settings = load_scene(scene).perturbation
    assert settings.max_duration == pytest.approx(0.1)
    assert settings.linear_acceleration == pytest.approx((0.2 * GRAVITY,) * 3)
    assert settings.angular_acceleration[2] == pytest.approx(0.667 * 0.2 * GRAVITY / 2.0, rel=1e-3)
    assert settings.likelihood_lambda == pytest.approx(3.46, abs=0.01)


def test_without_derive_a_key_left_out_takes_the_fixed_default(make_scene) -> None:
    settings = load_scene(make_scene(replace={SET_KEYS: ""})).perturbation
    assert settings.linear_acceleration == DEFAULTS["linear_acceleration"]
    assert settings.angular_acceleration == DEFAULTS["angular_acceleration"]
    assert (settings.max_duration, settings.likelihood_lambda) == (0.1, 5.0)
    assert settings.derived == {}


def test_derive_must_be_a_boolean(make_scene) -> None:
    scene = make_scene(replace={SET_KEYS: '[perturbation]\nderive = "yes"\n'})
    with pytest.raises(EnergyMarginError, match=r"scene.toml:\d+: perturbation.derive: must be true or false"):
        load_scene(scene)


def test_a_file_without_perturbation_keys_gets_derived_values(make_scene) -> None:
    loaded = load_scene(_derived_scene(make_scene))
    settings = loaded.perturbation
    assert set(settings.derived) == {"lambda", "max_duration", "linear_acceleration", "angular_acceleration"}
    # 1.5 s over 10 frames; friction [0.3, 0.6] -> mu 0.45.
    assert settings.max_duration == pytest.approx(PROPAGATION_PER_FRAME * 1.5 / 9)
    assert settings.linear_acceleration == pytest.approx((0.45 * GRAVITY,) * 3)
    # A 6 cm cube: radius of gyration sqrt(2 (0.03 * 2)^2 / 12) about every axis.
    gyration = np.sqrt(2 * 0.06**2 / 12)
    assert settings.angular_acceleration == pytest.approx((ANGULAR_RATIO * 0.45 * GRAVITY / gyration,) * 3, rel=1e-6)
    inertia = 0.1 * 2 * 0.06**2 / 12
    energy = (0.1 * 3 * (0.45 * GRAVITY) ** 2 + inertia * 3 * settings.angular_acceleration[0] ** 2) * (
        settings.max_duration**2
    )
    assert settings.likelihood_lambda == pytest.approx(LAMBDA_ENERGY / energy, rel=1e-6)
    # The task and its wrench bounds use them.
    from energy_margin.tasks.scene_task import SceneTask, SceneTaskConfig

    task = SceneTask(SceneTaskConfig(scene_file=str(loaded.spec.path)))
    assert task.config.likelihood_lambda == pytest.approx(settings.likelihood_lambda)
    limits = task.wrench_limits(task.build_scene(2, 0.5))
    assert limits.max_duration == pytest.approx(settings.max_duration)
    assert limits.max_wrench[0, 0] == pytest.approx(0.1 * 0.45 * GRAVITY)


def test_heavier_objects_get_a_proportionally_smaller_lambda(make_scene) -> None:
    light = load_scene(_derived_scene(make_scene)).perturbation
    heavy = load_scene(make_scene(replace={SET_KEYS: DERIVE}, model_replace={'mass="0.1"': 'mass="1.0"'})).perturbation
    # lambda times the energy of a full-bound perturbation stays the paper's: ten times the mass, a tenth of lambda.
    assert heavy.likelihood_lambda == pytest.approx(light.likelihood_lambda / 10, rel=1e-6)
    assert heavy.linear_acceleration == light.linear_acceleration


def test_the_friction_sets_the_linear_bound(make_scene) -> None:
    slippery = load_scene(_derived_scene(make_scene, friction="[0.1, 0.1]")).perturbation
    assert slippery.linear_acceleration[0] == pytest.approx(0.1 * GRAVITY)
    # Without randomize.friction: the objects' geoms' own (the tiny model's default class: 0.4).
    own = load_scene(make_scene(replace={SET_KEYS: DERIVE, "friction = [0.3, 0.6]\n": ""})).perturbation
    assert own.linear_acceleration[0] == pytest.approx(0.4 * GRAVITY)
    assert "objects' geoms" in own.derived["linear_acceleration"]


def test_keys_the_file_sets_are_kept(tiny_scene) -> None:
    settings = load_scene(tiny_scene).perturbation
    assert settings.linear_acceleration == (2.0, 2.0, 0.0)
    assert settings.angular_acceleration == (0.0, 0.0, 5.0)
    assert settings.max_duration == 0.1
    assert settings.likelihood_lambda == 5.0 and settings.derived == {}  # the tiny scene leaves lambda out
    loaded = load_scene(tiny_scene)
    assert resolve_perturbation(loaded.spec, loaded.model, loaded.object_bodies) == settings


def test_scene_prints_what_it_derived_and_why(make_scene, capsys) -> None:
    path = _derived_scene(make_scene)
    assert main(["scene", str(path), "--no-picture"]) == 0
    out = capsys.readouterr().out
    assert "derived perturbation.lambda (not in the file)" in out
    assert "derived perturbation.max_duration (not in the file): 0.45 of the 0.167 s between 10 frames" in out
    assert "mu = 0.45 (the middle of randomize.friction [0.3, 0.6])" in out
