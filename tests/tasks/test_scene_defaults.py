"""Perturbation settings derived from the scene when the file leaves them out (tasks/scene_defaults.py)."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

import mujoco
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
from energy_margin.tasks.scene_file import read_scene_file
from energy_margin.tasks.scene_model import load_scene

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"

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


def test_a_file_without_perturbation_gets_the_planar_default(make_scene) -> None:
    # Objects resting on a surface: pushes in its plane (world x-y) and a torque about its normal (z).
    loaded = load_scene(make_scene(replace={SET_KEYS: ""}))
    settings = loaded.perturbation
    assert settings.linear_acceleration == (2.0, 2.0, 0.0)
    assert settings.angular_acceleration == (0.0, 0.0, 20.0)
    assert {"perturbation.linear_acceleration", "perturbation.angular_acceleration"} <= loaded.spec.defaulted
    # A file that gives one bound keeps it; only the other takes its default.
    given = load_scene(make_scene(replace={SET_KEYS: "[perturbation]\nlinear_acceleration = [1.0, 1.0, 1.0]\n"}))
    assert given.perturbation.linear_acceleration == (1.0, 1.0, 1.0)
    assert given.perturbation.angular_acceleration == (0.0, 0.0, 20.0)


@pytest.mark.parametrize("gravity", ["0 0 0", "0 0 9.81", "0 0 -1"])
def test_gravity_along_z_or_none_takes_the_planar_default(make_scene, gravity: str) -> None:
    model = {'<option timestep="0.01"/>': f'<option timestep="0.01" gravity="{gravity}"/>'}
    settings = load_scene(make_scene(replace={SET_KEYS: ""}, model_replace=model)).perturbation
    assert (settings.linear_acceleration, settings.angular_acceleration) == ((2.0, 2.0, 0.0), (0.0, 0.0, 20.0))


def test_a_tilted_gravity_refuses_the_planar_default_in_one_line(make_scene) -> None:
    # Per-axis bounds cannot lie in a tilted plane: the file must give the bounds it leaves out.
    model = {'<option timestep="0.01"/>': '<option timestep="0.01" gravity="0 -4.9 -8.5"/>'}
    with pytest.raises(EnergyMarginError) as error:
        load_scene(make_scene(replace={SET_KEYS: ""}, model_replace=model))
    message = str(error.value)
    assert "\n" not in message
    assert message.endswith(
        "scene.toml: perturbation: the default bounds act in the world x-y plane with a torque about z, but "
        "model.xml's gravity (0, -4.9, -8.5) m/s^2 is not along z: give perturbation.linear_acceleration and "
        "perturbation.angular_acceleration"
    )
    only_linear = make_scene(
        replace={SET_KEYS: "[perturbation]\nlinear_acceleration = [2.0, 2.0, 2.0]\n"}, model_replace=model
    )
    with pytest.raises(EnergyMarginError, match=r"scene.toml:\d+: perturbation.angular_acceleration: .*give "):
        load_scene(only_linear)
    # Both bounds given: the file's own, whatever the gravity.
    settings = load_scene(make_scene(model_replace=model)).perturbation
    assert settings.linear_acceleration == (2.0, 2.0, 0.0)


def _written_perturbation(path: Path) -> dict[str, Any]:
    return tomllib.loads(path.read_text(encoding="utf-8")).get("perturbation", {})


EXAMPLE_SCENES = sorted(path for path in EXAMPLES.glob("*/*.toml") if _written_perturbation(path))


def test_every_example_scene_with_a_perturbation_table_is_found() -> None:
    assert len(EXAMPLE_SCENES) >= 8 and EXAMPLES / "pushing" / "pushing.toml" in EXAMPLE_SCENES


@pytest.mark.parametrize("path", EXAMPLE_SCENES, ids=lambda path: path.name)
def test_an_example_scene_keeps_the_perturbation_it_writes(path: Path) -> None:
    # Resolved against a stand-in model (gravity along -z; the examples' models are written by
    # scripts): the values come from the file alone, whatever the defaults.
    spec = read_scene_file(path)
    written = _written_perturbation(path)
    model = mujoco.MjModel.from_xml_string("<mujoco><worldbody/></mujoco>")
    settings = resolve_perturbation(spec, model, np.zeros(0, dtype=int))
    expected = {
        "linear_acceleration": settings.linear_acceleration,
        "angular_acceleration": settings.angular_acceleration,
        "max_duration": settings.max_duration,
        "lambda": settings.likelihood_lambda,
    }
    assert not written.get("derive", False) and settings.derived == {}
    for key, value in written.items():
        assert expected[key] == (tuple(value) if isinstance(value, list) else value), key
    assert not {f"perturbation.{key}" for key in written} & spec.defaulted


@pytest.mark.parametrize("path", sorted(EXAMPLES.glob("*/*.py")), ids=lambda path: f"{path.parent.name}/{path.name}")
def test_an_example_script_that_writes_a_perturbation_table_gives_both_bounds(path: Path) -> None:
    # Its bounds then never come from the default (the scripts need their own stacks to run).
    text = path.read_text(encoding="utf-8")
    if "[perturbation]" in text:
        assert "linear_acceleration = " in text and "angular_acceleration = " in text


def test_the_built_in_tasks_set_their_own_perturbation() -> None:
    # The paper's pushing bounds (2 m/s^2 in x and y, 0.667 rad/s^2 about z) and the scooping task's,
    # in their configurations: no scene default reaches them.
    from energy_margin.tasks.pushing import PushingConfig, PushingTask
    from energy_margin.tasks.scooping import ScoopingConfig

    pushing, scooping = PushingConfig(), ScoopingConfig()
    assert (pushing.max_linear_acceleration, pushing.max_angular_acceleration) == (2.0, 0.667)
    assert (scooping.max_linear_acceleration, scooping.max_angular_acceleration) == (2.0, 3.0)
    task = PushingTask()
    scene = task.build_scene(3, 0.5)
    limits = task.wrench_limits(scene).max_wrench
    np.testing.assert_allclose(limits[:, :2], np.repeat(scene.object_masses[:, None] * 2.0, 2, axis=1))
    np.testing.assert_allclose(limits[:, 2:5], 0.0)
    np.testing.assert_allclose(limits[:, 5], scene.object_inertias[:, 2] * 0.667)


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
