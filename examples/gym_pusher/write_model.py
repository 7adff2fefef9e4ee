"""Write gym_pusher_scene.xml and gym_pusher_motion.npz: Gymnasium's 7-DoF Pusher arm sweeping cylinders.

The arm is the one of ``Pusher-v5`` (gymnasium/envs/mujoco/assets/pusher_v5.xml), loaded with
``mujoco.MjSpec`` as Gymnasium ships it. The environment's own puck (``object``) and goal disc
(``goal``) ride on slide joints and are removed; a goal site stays where the disc was. The model has
no gravity and torque motors; here gravity is switched on (the arm's links are gravity-compensated,
the objects are not), every arm joint gets a position servo and one free cylinder body is the object
template the scene file copies. The arm's U-shaped tip (three capsules on its wrist roll link, the
only arm geoms that collide) is the pusher. Inverse kinematics with MuJoCo's Jacobians gives the arm
poses that move the tip along a straight line across the table, the U level and its opening facing
the sweep; they are the control rows of the motion file.

Both files are checked in beside ``gym_pusher.toml`` (no machine's paths in them), so the script
writes to ``runs/examples/gym_pusher/`` under the current folder by default and leaves the
checked-in copies as they are; ``--out examples/gym_pusher`` replaces them on purpose.

    python examples/gym_pusher/write_model.py [--out DIR]
"""

from __future__ import annotations

import argparse
import importlib.util
import shutil
import sys
from pathlib import Path

import mujoco
import numpy as np

from energy_margin.compat import delete_element, set_joint_coefficient, set_to_position, spec_xml

#: Where the files go without ``--out``: not beside the scene file, whose copies are checked in.
DEFAULT_OUT = Path("runs/examples/gym_pusher")
ARM_JOINTS = (
    "r_shoulder_pan_joint",
    "r_shoulder_lift_joint",
    "r_upper_arm_roll_joint",
    "r_elbow_flex_joint",
    "r_forearm_roll_joint",
    "r_wrist_flex_joint",
    "r_wrist_roll_joint",
)
#: Position servo gains of the first four joints and of the three wrist joints: stiffness N m/rad.
ARM_KP = (200.0, 50.0)
#: and damping N m s/rad.
ARM_KV = (20.0, 5.0)
#: The table plane of pusher_v5.xml is at this height (m).
TABLE_Z = -0.325
#: The object template: an upright cylinder, radius and half height (m), mass (kg).
CYLINDER = (0.03, 0.04, 0.1)
#: The tip site: the centre of the U, in the wrist roll link's frame (m).
TIP = (0.05, 0.0, 0.0)
#: Where Pusher-v5's goal disc is (m).
GOAL = (0.45, -0.05, TABLE_Z)


def pusher_xml() -> Path:
    """pusher_v5.xml where pip installed gymnasium (exits with one line when it is missing)."""
    spec = importlib.util.find_spec("gymnasium")
    if spec is None or spec.origin is None:
        sys.exit("this example needs gymnasium: pip install 'energy-margin[examples]'")
    return Path(spec.origin).resolve().parent / "envs" / "mujoco" / "assets" / "pusher_v5.xml"


def build_spec() -> mujoco.MjSpec:
    """The Pusher arm without the environment's puck and goal, with gravity, servos, a tip site and a cylinder."""
    spec = mujoco.MjSpec.from_file(str(pusher_xml()))
    spec.modelname = "gym_pusher_scene"
    spec.option.gravity = [0.0, 0.0, -9.81]
    spec.option.timestep = 0.005
    # pusher_v5.xml's Euler integrator stays: with implicitfast (MuJoCo 4.0.0) a cylinder spinning fast
    # after it tipped over gained about 1000 rad/s in one step, with no contact, in one trajectory of 20.
    for name in ("object", "goal"):
        delete_element(spec, spec.body(name))
    # The table is a plane (it collides everywhere); drawn 0.2 m longer towards the arm's base, under the tip's start.
    spec.geom("table").size = [1.0, 1.2, 0.1]
    for body in spec.bodies:
        if body.name.startswith("r_") or body.name == "tips_arm":
            body.gravcomp = 1.0
    spec.body("r_wrist_roll_link").add_site(name="tip", pos=list(TIP))
    for actuator in list(spec.actuators):
        delete_element(spec, actuator)
    for index, joint in enumerate(ARM_JOINTS):
        actuator = spec.add_actuator(name=f"servo_{joint[2:-6]}", target=joint)
        actuator.trntype = mujoco.mjtTrn.mjTRN_JOINT
        wrist = index >= 4
        set_to_position(actuator, kp=ARM_KP[wrist], kv=ARM_KV[wrist])
        actuator.forcelimited = True
        actuator.forcerange = [-15.0, 15.0] if wrist else [-60.0, 60.0]
    world = spec.worldbody
    world.add_site(name="goal", pos=list(GOAL))
    radius, half_height, mass = CYLINDER
    cylinder = world.add_body(name="cylinder", pos=[0.0, 0.0, TABLE_Z + half_height])
    joint = cylinder.add_freejoint()
    # pusher_v5.xml's default class gives joints damping 1 and armature 0.04: none for the objects.
    set_joint_coefficient(joint, "damping", 0.0)
    joint.armature = 0.0
    # and geoms condim 1 (frictionless) and no collisions: the cylinders collide, with friction.
    cylinder.add_geom(
        type=mujoco.mjtGeom.mjGEOM_CYLINDER,
        size=[radius, half_height, 0.0],
        mass=mass,
        contype=1,
        conaffinity=1,
        condim=3,
        rgba=[0.95, 0.55, 0.15, 1.0],
    )
    return spec


def solve_pose(model: mujoco.MjModel, target: np.ndarray, direction: np.ndarray, seed: np.ndarray) -> np.ndarray:
    """Arm joints that put the tip site at ``target`` (m), the U level and opening along ``direction``."""
    data = mujoco.MjData(model)
    site = model.site("tip").id
    wrist = model.body("r_wrist_roll_link").id
    joints = [model.joint(name).id for name in ARM_JOINTS]
    qpos = model.jnt_qposadr[joints]
    dofs = model.jnt_dofadr[joints]
    low, high = model.jnt_range[joints, 0], model.jnt_range[joints, 1]
    q = seed.copy()
    for _ in range(3000):
        data.qpos[qpos] = q
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        jac_pos = np.zeros((3, model.nv))
        jac_rot = np.zeros((3, model.nv))
        mujoco.mj_jacSite(model, data, jac_pos, jac_rot, site)
        error_pos = target - data.site_xpos[site]
        # The U is symmetric about its plane: its normal (the link's z) may point up or down.
        rotation = data.xmat[wrist].reshape(3, 3)
        normal = rotation[:, 2] * (1.0 if rotation[2, 2] >= 0 else -1.0)
        error_rot = np.cross(normal, [0.0, 0.0, 1.0]) + np.cross(rotation[:, 0], direction)
        error = np.concatenate([error_pos, 0.3 * error_rot])
        if np.linalg.norm(error) < 1e-6:
            break
        jac = np.vstack([jac_pos, 0.3 * jac_rot])[:, dofs]
        step = jac.T @ np.linalg.solve(jac @ jac.T + 1e-4 * np.eye(6), error)
        q = np.clip(q + np.clip(step, -0.2, 0.2), low, high)
    if np.linalg.norm(error_pos) > 1e-3 or np.linalg.norm(error_rot) > 1e-2:
        sys.exit(f"no arm pose puts the tip at {target.tolist()} (left {np.linalg.norm(error_pos):.3g} m away)")
    return q


#: The sweep: the tip moves along +y at this x and height above the table (m), between these y (m).
SWEEP_X = 0.45
SWEEP_HEIGHT = 0.035
SWEEP_Y = (-0.55, -0.09)
#: Times (s): hold the start, sweep, hold the end.
SWEEP_TIMES = (0.3, 2.8, 3.4)
#: A start of the inverse kinematics on the branch that reaches the whole line (found once by random search).
IK_SEED = np.array([-0.98, 0.96, -1.5, -1.66, -1.03, -0.99, -1.43])


def main() -> None:
    """Solve the sweep, then write the scene's model (with a start keyframe) and its motion file."""
    parser = argparse.ArgumentParser(description="write gym_pusher_scene.xml and gym_pusher_motion.npz")
    parser.add_argument(
        "--out",
        type=Path,
        default=DEFAULT_OUT,
        help=f"folder to write them to (default: {DEFAULT_OUT}; examples/gym_pusher replaces the checked-in copies)",
    )
    out = parser.parse_args().out
    out.mkdir(parents=True, exist_ok=True)
    spec = build_spec()
    model = spec.compile()
    direction = np.array([0.0, 1.0, 0.0])
    ys = np.linspace(*SWEEP_Y, 15)
    poses = []
    q = IK_SEED
    for y in ys:
        q = solve_pose(model, np.array([SWEEP_X, y, TABLE_Z + SWEEP_HEIGHT]), direction, q)
        poses.append(q.copy())
    hold, sweep_end, end = SWEEP_TIMES
    times = np.concatenate([[0.0], np.linspace(hold, sweep_end, len(ys)), [end]])
    ctrl = np.vstack([poses[0], poses, poses[-1]])
    half_height = CYLINDER[1]
    start = np.concatenate([poses[0], [SWEEP_X, -0.35, TABLE_Z + half_height, 1.0, 0.0, 0.0, 0.0]])
    spec.add_key(name="start", qpos=start.tolist())
    (out / "gym_pusher_scene.xml").write_text(spec_xml(spec))
    np.savez(out / "gym_pusher_motion.npz", time=times, ctrl=ctrl)
    scene = Path(__file__).with_name("gym_pusher.toml")
    if out.resolve() != scene.parent.resolve():
        # The scene file beside the fresh copies reads them: the model as this MuJoCo writes it
        # (the checked-in one is MuJoCo 4.0's, which MuJoCo 3.x does not read).
        shutil.copy(scene, out / scene.name)
    print(f"wrote {out / 'gym_pusher_scene.xml'} and {out / 'gym_pusher_motion.npz'} ({len(times)} control rows)")


if __name__ == "__main__":
    main()
