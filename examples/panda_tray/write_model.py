"""Write panda_scene.xml and panda_motion.npz: the Franka Panda of Gymnasium-Robotics carrying a tray.

The arm is Gymnasium-Robotics' Franka Panda of its Franka Kitchen environment
(``gymnasium_robotics/envs/assets/kitchen_franka/franka_assets/``: ``assets.xml`` holds the
meshes and defaults, ``chain.xml`` the arm and hand, ``actuator.xml`` its position servos; all
three are ``<mujocoinclude>`` fragments). A small wrapper model includes them by absolute path and
is then edited with ``mujoco.MjSpec``:

* the arm stands on the floor at the origin; its links and the tray (a known payload) compensate
  gravity (``gravcomp``), as the Panda's own controller does; the arm's seven position servos get
  the stiffness and damping gains of MuJoCo Menagerie's Panda (the package's own servos have no
  damping gain and its joints a damping of 100 N m s/rad, which at the carry's speed would take
  more than the servos' 87 N m), within the package's force limits;
* time step 4 ms (the package's is 2 ms) with the implicit integrator;
* a flat tray (30 cm x 24 cm, 1 cm thick, no rims) is fixed to the hand (a child body of
  ``panda0_link7``): the hand points horizontally and the closed fingers pinch the tray's near
  edge; the tray's frame (site ``tray``, at the centre of its top face) has z up and x pointing
  away from the hand;
* a stand under the tray's start pose, a floor, and one 4 cm box (the template the scene file
  copies).

The motion: the tray rests just above its stand for 0.3 s, is lifted 8 cm, carried around the
robot in a quarter circle (its centre 0.70 m from the base axis, heading +x at the start and +y at
the end: a 90 degree turn), and held at the destination. Each leg follows a minimum-jerk time law.
The arm's joint targets along the way are solved by inverse kinematics (damped least squares on
mujoco's Jacobians) every 0.05 s and written as the control rows of ``panda_motion.npz``. The
meshes stay where pip installed gymnasium-robotics: the written model points at them by absolute
path, so run this script once after ``pip install 'energy-margin[examples]'``.

    python examples/panda_tray/write_model.py
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
from pathlib import Path

import mujoco
import numpy as np

from energy_margin.compat import set_asset_dirs, set_joint_coefficient, set_to_position, spec_xml

HERE = Path(__file__).resolve().parent
ARM_JOINTS = tuple(f"robot:panda0_joint{i}" for i in range(1, 8))
#: Arm servo stiffness (N m/rad) and damping (N m s/rad), and the arm joints' own damping
#: (N m s/rad) and armature (kg m^2): the values of MuJoCo Menagerie's Panda model. The package's
#: joint damping (100 N m s/rad) alone would take the servos' whole 87 N m force limit at 0.9 rad/s.
ARM_KP = (4500.0, 4500.0, 3500.0, 3500.0, 2000.0, 2000.0, 2000.0)
ARM_KV = (450.0, 450.0, 350.0, 350.0, 200.0, 200.0, 200.0)
JOINT_DAMPING, JOINT_ARMATURE = 1.0, 0.1
#: Finger servo target (m per finger): closed on the tray's 1 cm thick edge.
FINGER = 0.005
#: Tray: half sizes (m) of the flat plate (no rims) and its mass (kg).
TRAY_HALF = (0.15, 0.12, 0.005)
TRAY_MASS = 0.4
#: How far along the hand's approach axis (link7's z, m) the tray's near edge sits: the fingertips
#: (from about 0.20 m to 0.255 m) overlap its first 4 cm.
TRAY_EDGE = 0.215
#: Box: half size (m) and mass (kg).
BOX_HALF, BOX_MASS = 0.02, 0.1
#: The path of the tray's top face centre: distance from the base axis (m), heights (m), turn (rad).
RADIUS = 0.70
START_HEIGHT, CARRY_HEIGHT = 0.68, 0.76
TURN = np.pi / 2
#: Times (s): hold, lift until, carry until, end.
T_HOLD, T_LIFT, T_CARRY, T_END = 0.3, 0.9, 2.6, 3.2
#: Control rows every this many seconds.
STEP = 0.05
#: The inverse kinematics' preferred arm configuration (rad): elbow up, the hand level, the fingers
#: closing vertically.
READY = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, -1.57])


def franka_dir() -> Path:
    """The folder of the Franka Panda fragments in the installed gymnasium-robotics (without importing it)."""
    found = importlib.util.find_spec("gymnasium_robotics")
    if found is None or found.origin is None:
        sys.exit("this example needs gymnasium-robotics: pip install 'energy-margin[examples]'")
    return Path(found.origin).resolve().parent / "envs" / "assets" / "kitchen_franka" / "franka_assets"


def build_spec() -> mujoco.MjSpec:
    """The Panda on the floor with its tray, the start stand and one box."""
    root = franka_dir()
    wrapper = f"""<mujoco model="panda_tray">
  <include file="{root / "assets.xml"}"/>
  <worldbody>
    <include file="{root / "chain.xml"}"/>
  </worldbody>
  <include file="{root / "actuator.xml"}"/>
</mujoco>"""
    spec = mujoco.MjSpec.from_string(wrapper)
    # assets.xml names its meshes relative to its meshdir, franka_assets/meshes, which the include
    # resolves from the fragment's own folder: point each mesh at its file by absolute path.
    set_asset_dirs(spec, meshdir="")
    for mesh in spec.meshes:
        mesh.file = str(root / "meshes" / Path(mesh.file).relative_to(root))
    spec.option.timestep = 0.004
    # The implicit integrator: with "implicitfast" (and with Euler) boxes rocking on the turning
    # tray now and then gain energy at this time step and fly off.
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICIT
    for body in spec.bodies:
        if body.name.startswith("panda0_"):
            body.gravcomp = 1.0
    for name, actuator, kp, kv in zip(ARM_JOINTS, spec.actuators[:7], ARM_KP, ARM_KV, strict=True):
        set_to_position(actuator, kp=kp, kv=kv)  # force = kp (ctrl - q) - kv qdot, within +-87 / 12 N m
        set_joint_coefficient(spec.joint(name), "damping", JOINT_DAMPING)
        spec.joint(name).armature = JOINT_ARMATURE
    world = spec.worldbody
    world.add_light(pos=[0.3, 0.3, 2.5], dir=[0, 0, -1], diffuse=[0.7, 0.7, 0.7])
    world.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[2, 2, 0.1], rgba=[0.75, 0.75, 0.75, 1])
    # The tray's frame in link7's: x along the hand's approach axis (link7 z), z along the fingers'
    # closing axis (the hand's y, link7's y turned by -45 degrees about z).
    c, s = np.cos(-np.pi / 4), np.sin(-np.pi / 4)
    hand_y = np.array([-s, c, 0.0])
    x_axis = np.array([0.0, 0.0, 1.0])
    z_axis = hand_y
    y_axis = np.cross(z_axis, x_axis)
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.column_stack([x_axis, y_axis, z_axis]).ravel())
    plate_centre = TRAY_EDGE + TRAY_HALF[0]
    tray = spec.body("panda0_link7").add_body(
        name="tray", pos=[0.0, 0.0, plate_centre], quat=quat.tolist(), gravcomp=1.0
    )
    colour = [0.55, 0.35, 0.2, 1.0]
    top = TRAY_HALF[2]
    tray.add_geom(name="tray_plate", type=mujoco.mjtGeom.mjGEOM_BOX, size=list(TRAY_HALF), mass=TRAY_MASS, rgba=colour)
    tray.add_site(name="tray", pos=[0.0, 0.0, top])
    for finger in ("panda0_leftfinger", "panda0_rightfinger"):
        spec.add_exclude(bodyname1="tray", bodyname2=finger)
    stand_top = START_HEIGHT - 2 * TRAY_HALF[2] - 0.002
    world.add_geom(
        name="stand",
        type=mujoco.mjtGeom.mjGEOM_BOX,
        size=[0.1, 0.1, stand_top / 2],
        pos=[RADIUS + 0.03, 0.0, stand_top / 2],
        rgba=[0.4, 0.4, 0.45, 1],
    )
    box = world.add_body(name="box")
    box.add_freejoint()
    box.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[BOX_HALF] * 3, mass=BOX_MASS, rgba=[0.95, 0.55, 0.15, 1])
    return spec


def tray_pose(t: float) -> tuple[np.ndarray, float]:
    """The tray's top centre (m) and heading (rad about z) at time ``t`` (s) of the motion."""

    def min_jerk(t0: float, t1: float) -> float:
        u = float(np.clip((t - t0) / (t1 - t0), 0.0, 1.0))
        return u**3 * (10 - 15 * u + 6 * u**2)

    height = START_HEIGHT + (CARRY_HEIGHT - START_HEIGHT) * min_jerk(T_HOLD, T_LIFT)
    angle = TURN * min_jerk(T_LIFT, T_CARRY)
    return np.array([RADIUS * np.cos(angle), RADIUS * np.sin(angle), height]), angle


def solve_pose(model: mujoco.MjModel, target: np.ndarray, heading: float, q: np.ndarray) -> np.ndarray:
    """Arm joints that put the tray's top centre at ``target`` (m), level, its x axis at ``heading``."""
    data = mujoco.MjData(model)
    joints = [model.joint(name).id for name in ARM_JOINTS]
    address, dofs = model.jnt_qposadr[joints], model.jnt_dofadr[joints]
    low, high = model.jnt_range[joints, 0], model.jnt_range[joints, 1]
    site = model.site("tray").id
    want = np.array([[np.cos(heading), -np.sin(heading), 0.0], [np.sin(heading), np.cos(heading), 0.0], [0, 0, 1]])
    for _ in range(500):
        data.qpos[address] = q
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        jac_pos = np.zeros((3, model.nv))
        jac_rot = np.zeros((3, model.nv))
        mujoco.mj_jacSite(model, data, jac_pos, jac_rot, site)
        rotation = data.site_xmat[site].reshape(3, 3)
        error_pos = target - data.site_xpos[site]
        error_rot = 0.5 * sum(np.cross(rotation[:, i], want[:, i]) for i in range(3))
        error = np.concatenate([error_pos, error_rot])
        jac = np.vstack([jac_pos, jac_rot])[:, dofs]
        inverse = jac.T @ np.linalg.inv(jac @ jac.T + 1e-4 * np.eye(6))
        # Towards the ready posture in the task's null space.
        step = inverse @ error + 0.1 * (np.eye(7) - inverse @ jac) @ (READY - q)
        q = np.clip(q + np.clip(step, -0.1, 0.1), low, high)
        if np.linalg.norm(error) < 1e-8:
            break
    if np.linalg.norm(error_pos) > 1e-4 or np.linalg.norm(error_rot) > 1e-3:
        sys.exit(
            f"no arm pose puts the tray at {target.round(3).tolist()} (left {np.linalg.norm(error_pos):.3g} m away)"
        )
    return q


def main() -> None:
    """Write panda_scene.xml (with the ``start`` key) and panda_motion.npz to ``--out``."""
    parser = argparse.ArgumentParser(description="write panda_scene.xml and panda_motion.npz")
    parser.add_argument("--out", type=Path, default=HERE, help="folder to write them to (default: beside this script)")
    out = parser.parse_args().out
    out.mkdir(parents=True, exist_ok=True)
    spec = build_spec()
    model = spec.compile()
    times = np.round(np.arange(0.0, T_END + STEP / 2, STEP), 6)
    q = READY.copy()
    rows = []
    for t in times:
        target, heading = tray_pose(t)
        q = solve_pose(model, target, heading, q)
        rows.append(q.copy())
    arm = np.array(rows)
    ctrl = np.hstack([arm, np.full((len(times), 2), FINGER)])
    qpos = model.qpos0.copy()
    joints = [model.joint(name).id for name in ARM_JOINTS]
    qpos[model.jnt_qposadr[joints]] = arm[0]
    for name in ("robot:panda0_finger_joint1", "robot:panda0_finger_joint2"):
        qpos[model.jnt_qposadr[model.joint(name).id]] = FINGER
    spec.add_key(name="start", qpos=qpos.tolist(), ctrl=ctrl[0].tolist())
    (out / "panda_scene.xml").write_text(spec_xml(spec))
    np.savez(out / "panda_motion.npz", time=times, ctrl=ctrl)
    print(f"wrote {out / 'panda_scene.xml'} and {out / 'panda_motion.npz'} ({len(times)} control rows)")
    print(f"arm at the start: {np.round(arm[0], 3).tolist()} rad")


if __name__ == "__main__":
    main()
