"""A scene file driven by actuator controls is controllable; one moving mocap bodies is refused."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from energy_margin.control.commands import SceneCommands, command_space
from energy_margin.control.episodes import run_control
from energy_margin.control.mppi import ControllerConfig
from energy_margin.errors import EnergyMarginError
from energy_margin.tasks import get_task

# A box in front of a pusher on a slide joint with a motor; the declared motion commands nothing,
# so only a controller that pushes brings the box into the band 0.25-0.45 m ahead.
MODEL = """<mujoco model="slider_push">
  <option timestep="0.01"/>
  <default><geom friction="0.4"/></default>
  <worldbody>
    <geom name="ground" type="plane" size="2 2 0.1"/>
    <body name="pusher" pos="0 -0.15 0.03">
      <joint name="pusher_y" type="slide" axis="0 1 0" damping="5"/>
      <geom name="pusher" type="box" size="0.15 0.02 0.03" mass="1"/>
    </body>
    <body name="box_a" pos="0 0 0.03"><freejoint/><geom type="box" size="0.03 0.03 0.03" mass="0.1"/></body>
  </worldbody>
  <actuator><motor name="push" joint="pusher_y" ctrlrange="-5 5" ctrllimited="true"/></actuator>
</mujoco>
"""

SCENE = """schema_version = 1
mjcf = "model.xml"

[objects]
bodies = ["box_a"]

[motion]
duration = 1.0

[[motion.keyframes]]
time = 0.0
ctrl = [0.0]

[randomize]
friction = [0.3, 0.5]

[randomize.start]
x = [-0.05, 0.05]
y = [-0.02, 0.02]

[perturbation]
linear_acceleration = [2.0, 2.0, 0.0]
angular_acceleration = [0.0, 0.0, 5.0]
max_duration = 0.1

[capture]
region = { type = "box", body = "pusher", center = [0.0, 0.12, 0.0], half_size = [0.2, 0.1, 0.1] }

[success]
region = { type = "box", center = [0.0, 0.35, 0.03], half_size = [0.3, 0.1, 0.1] }
"""


@pytest.fixture
def motor_scene(tmp_path: Path) -> Path:
    (tmp_path / "model.xml").write_text(MODEL)
    path = tmp_path / "scene.toml"
    path.write_text(SCENE)
    return path


def test_scene_commands_are_the_declared_actuators(motor_scene: Path) -> None:
    task = get_task("scene", {"scene_file": str(motor_scene)})
    space = command_space(task, 1)
    assert isinstance(space, SceneCommands)
    assert space.names == ("push",)
    np.testing.assert_array_equal(space.low, [-5.0])
    np.testing.assert_array_equal(space.high, [5.0])
    inputs = space.inputs(np.array([[[9.0], [-1.0]]]), held=None, start_time=0.0, dt=0.01, period_steps=3)
    assert inputs.ctrl is not None
    np.testing.assert_array_equal(inputs.ctrl[0, :, 0], [5.0, 5.0, 5.0, -1.0, -1.0, -1.0])


def test_controller_pushes_a_scene_box_the_declared_motion_leaves(tmp_path: Path, motor_scene: Path) -> None:
    options = {
        "n_objects": 1,
        "episodes": 2,
        "disturbance": "none",
        "seed": 0,
        "score_expansions": 0,
        "task_overrides": {"scene_file": str(motor_scene)},
    }
    scripted, _ = run_control("scene", policy="scripted", out=tmp_path / "s", **options)  # type: ignore[arg-type]
    controlled, _ = run_control(
        "scene",
        policy="task",
        out=tmp_path / "t",
        controller=ControllerConfig(samples=8, horizon=6),
        **options,  # type: ignore[arg-type]
    )
    assert scripted.successes == 0
    assert controlled.successes == 2


def test_a_scene_moving_mocap_bodies_is_refused(tiny_scene: Path) -> None:
    task = get_task("scene", {"scene_file": str(tiny_scene)})
    with pytest.raises(EnergyMarginError, match="moves mocap bodies"):
        command_space(task, 2)
