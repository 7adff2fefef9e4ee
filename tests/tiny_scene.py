"""The tiny user scene of the tests: a MuJoCo model of two free boxes and a mocap pusher, and its scene file.

A module of its own (not ``conftest``) so test modules can import it by a name no other folder's
``conftest`` shadows.
"""

from __future__ import annotations

from pathlib import Path

# A tiny user scene: two free boxes on the ground and a mocap pusher that moves them along +y.
TINY_MODEL = """<mujoco model="two_boxes">
  <option timestep="0.01"/>
  <default><geom friction="0.4"/></default>
  <worldbody>
    <geom name="ground" type="plane" size="2 2 0.1"/>
    <site name="goal" pos="0 0.4 0.03"/>
    <body name="pusher" mocap="true" pos="0 -0.15 0.03">
      <geom name="pusher" type="box" size="0.15 0.02 0.03"/>
    </body>
    <body name="box_a" pos="-0.06 0 0.03"><freejoint/><geom type="box" size="0.03 0.03 0.03" mass="0.1"/></body>
    <body name="box_b" pos="0.06 0 0.03"><freejoint/><geom type="box" size="0.03 0.03 0.03" mass="0.1"/></body>
  </worldbody>
</mujoco>
"""

TINY_SCENE = """schema_version = 1
mjcf = "model.xml"

[objects]
bodies = ["box_*"]

[motion]
duration = 1.5

[[motion.keyframes]]
time = 0.0
mocap.pusher.pos = [0.0, -0.15, 0.03]

[[motion.keyframes]]
time = 1.5
mocap.pusher.pos = [0.0, 0.3, 0.03]

[randomize]
friction = [0.3, 0.6]

[randomize.start]
x = [-0.12, 0.12]
y = [-0.02, 0.08]
yaw = [-0.3, 0.3]

[perturbation]
linear_acceleration = [2.0, 2.0, 0.0]
angular_acceleration = [0.0, 0.0, 5.0]
max_duration = 0.1

[capture]
region = { type = "box", body = "pusher", center = [0.0, 0.12, 0.0], half_size = [0.2, 0.1, 0.1] }

[success]
region = { type = "all", of = [
  { type = "distance", site = "goal", max = 0.16 },
  { type = "height", max = 0.1 },
] }
"""


#: A slide pad driven by a position actuator, added to :data:`TINY_MODEL` (``make_scene``'s
#: ``model_replace``): the tiny scene's robot with an actuator beside its mocap pusher.
SLIDE_PAD = {
    "  </worldbody>": '  <body name="pad" pos="0.5 0 0.03"><joint name="pad_x" type="slide" axis="1 0 0"/>'
    '<geom type="box" size="0.02 0.02 0.02"/></body>\n  </worldbody>',
    "</mujoco>": '<actuator><position joint="pad_x" kp="10"/></actuator>\n</mujoco>',
}


# An arm swept by a motor about a base at ``height``: its link pushes a box across the ground; two
# slide fingers on the link can close onto each other (robot self-contact). With the default height
# the link rests clear of the ground; a lower one lays it on the ground.
SWEEPING_ARM = """<mujoco>
  <option timestep="{timestep}"/>
  <worldbody>
    <geom name="ground" type="plane" size="2 2 0.1"/>
    <body name="base" pos="0 0 {height}">
      <joint name="shoulder" type="hinge" axis="0 0 1" damping="0.1"/>
      <geom name="link" type="capsule" fromto="0 0 0 0.4 0 0" size="0.02" mass="0.5"/>
      <site name="tip" pos="0.4 0 0"/>
      <body name="left" pos="0.45 0.03 0">
        <joint name="left" type="slide" axis="0 1 0" range="-0.05 0.05"/>
        <geom name="left" type="box" size="0.01 0.01 0.01" mass="0.05"/>
      </body>
      <body name="right" pos="0.45 -0.03 0">
        <joint name="right" type="slide" axis="0 1 0" range="-0.05 0.05"/>
        <geom name="right" type="box" size="0.01 0.01 0.01" mass="0.05"/>
      </body>
    </body>
    <body name="box" pos="0.3 0.12 0.03"><freejoint/><geom type="box" size="0.03 0.03 0.03" mass="0.2"/></body>
  </worldbody>
  <actuator>
    <motor joint="shoulder" gear="1"/>
    <position joint="left" kp="50"/>
    <position joint="right" kp="50"/>
  </actuator>
</mujoco>
"""


def sweeping_arm(*, height: float = 0.05, timestep: float = 0.002) -> str:
    """The MJCF of :data:`SWEEPING_ARM` with its base at ``height`` (m) and its time step (s)."""
    return SWEEPING_ARM.format(height=height, timestep=timestep)


# A hinged arm over a puck on two slides (the arm sweeps through the puck at about 0.46 rad).
ARM_AND_PUCK = """<mujoco>
  <option timestep="0.01"/>
  <worldbody>
    <geom type="plane" size="2 2 0.1"/>
    <body name="arm" pos="0 0 0.05">
      <joint name="shoulder" type="hinge" axis="0 0 1"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02" mass="1"/>
      <site name="tip" pos="0.3 0 0"/>
    </body>
    <body name="puck" pos="{x} {y} 0.03">
      <joint name="puck_y" type="slide" axis="0 1 0"/>
      <joint name="puck_x" type="slide" axis="1 0 0"/>
      <geom type="cylinder" size="0.03 0.03" mass="0.1"/>
    </body>
  </worldbody>
  <actuator><position joint="shoulder" kp="50"/></actuator>
</mujoco>
"""

ARM_AND_PUCK_SCENE = """schema_version = 1
mjcf = "model.xml"

[objects]
bodies = ["puck"]
joints = "upright"

[motion]
duration = DURATION
ROBOT

[capture]
region = { type = "distance", site = "tip", max = 0.2 }

[success]
region = { type = "height", max = 0.1 }
"""

#: The arm sweeps through the puck (at about 0.46 rad of its turn).
ARM_OVER_PUCK = ARM_AND_PUCK.format(x=0.2, y=0.1)
#: The arm's scene over two seconds; ``ROBOT`` is replaced by the motion's ``robot`` line.
ARM_SCENE = ARM_AND_PUCK_SCENE.replace("DURATION", "2.0")


def write_arm_rollouts(directory: Path, *, count: int = 3, rows: int = 150) -> list[Path]:
    """``count`` recorded roll-outs of :data:`ARM_OVER_PUCK` (``.npz``: time, qpos, qvel every step).

    The arm's servo turns it from 0 to 0.9, 1.0, ... rad (ramped over 0.6 s) through the puck.
    """
    import mujoco
    import numpy as np

    directory.mkdir(parents=True, exist_ok=True)
    model = mujoco.MjModel.from_xml_string(ARM_OVER_PUCK)
    paths = []
    for index in range(count):
        data = mujoco.MjData(model)
        time, qpos, qvel = [], [], []
        for step in range(rows):
            data.ctrl[0] = (0.9 + 0.1 * index) * min(1.0, step / 60)
            time.append(data.time)
            qpos.append(data.qpos.copy())
            qvel.append(data.qvel.copy())
            mujoco.mj_step(model, data)
        path = directory / f"rollout_{index}.npz"
        np.savez(path, time=np.array(time), qpos=np.array(qpos), qvel=np.array(qvel))
        paths.append(path)
    return paths


def write_tiny_scene(directory: Path, scene: str = TINY_SCENE, model: str = TINY_MODEL) -> Path:
    """Write the tiny model and scene file into ``directory``; return the scene file's path."""
    directory.mkdir(parents=True, exist_ok=True)
    (directory / "model.xml").write_text(model)
    path = directory / "scene.toml"
    path.write_text(scene)
    return path
