"""Write jaco_scene.xml: the Kinova Jaco arm and three-finger hand that dm_control ships, on a floor.

The arm (dm_control/third_party/kinova/jaco_arm.xml) and hand (jaco_hand.xml), with their own
meshes, are loaded and joined with ``mujoco.MjSpec`` (the hand attached at the arm's wrist site).
dm_control adds the arm's actuators in Python; here every arm joint gets a position servo and each
finger a position servo, added with MjSpec. A flat paddle is fixed to the hand (the tool that
pushes), and one box body is the object template the scene file copies. The meshes stay where pip
installed dm_control: the written model points at them by absolute path, so run this script once
after ``pip install 'energy-margin[examples]'`` (it prints the arm's start pose it solved for).

    python examples/jaco/write_model.py
"""

from __future__ import annotations

import sys
from pathlib import Path

import mujoco
import numpy as np

from energy_margin.compat import set_asset_dirs, set_to_position, spec_xml

HERE = Path(__file__).resolve().parent
#: Arm joint servo gains: stiffness N m/rad and damping N m s/rad.
ARM_KP, ARM_KV = 300.0, 30.0
#: Paddle centre in the hand frame (m) and half sizes (m).
PADDLE_POS = (0.0, 0.0, -0.16)
PADDLE_HALF = (0.12, 0.01, 0.035)


def kinova_dir() -> Path:
    try:
        import dm_control
    except ImportError:
        sys.exit("this example needs dm_control: pip install 'energy-margin[examples]'")
    return Path(dm_control.__file__).resolve().parent / "third_party" / "kinova"


def build_spec() -> mujoco.MjSpec:
    root = kinova_dir()
    arm = mujoco.MjSpec.from_file(str(root / "jaco_arm.xml"))
    hand = mujoco.MjSpec.from_file(str(root / "jaco_hand.xml"))
    arm.attach(hand, site=arm.site("wristsite"), prefix="hand_")
    arm.modelname = "jaco_scene"
    arm.option.timestep = 0.004
    set_asset_dirs(arm, meshdir=str(root / "meshes_decimated"))
    world = arm.worldbody
    world.add_light(pos=[0, 0, 2.5], dir=[0, 0, -1])
    world.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[2, 2, 0.1], rgba=[0.75, 0.75, 0.75, 1])
    paddle = arm.body("hand_hand")
    paddle.add_geom(
        name="paddle",
        type=mujoco.mjtGeom.mjGEOM_BOX,
        size=list(PADDLE_HALF),
        pos=list(PADDLE_POS),
        mass=0.05,
        rgba=[0.2, 0.5, 0.9, 1],
    )
    paddle.add_site(name="paddle_centre", pos=list(PADDLE_POS))
    world.add_site(name="goal", pos=[0.0, 0.45, 0.0])
    box = world.add_body(name="box")
    box.add_freejoint()
    box.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.025, 0.025, 0.025], mass=0.05, rgba=[0.95, 0.55, 0.15, 1])
    for index in range(1, 7):
        actuator = arm.add_actuator(name=f"arm_{index}", target=f"joint_{index}")
        actuator.trntype = mujoco.mjtTrn.mjTRN_JOINT
        set_to_position(actuator, kp=ARM_KP, kv=ARM_KV)
        actuator.forcelimited = True
        actuator.forcerange = [-40.0, 40.0] if index <= 3 else [-15.0, 15.0]
    for index in range(1, 4):
        actuator = arm.add_actuator(name=f"finger_{index}", target=f"hand_finger_{index}")
        actuator.trntype = mujoco.mjtTrn.mjTRN_JOINT
        set_to_position(actuator, kp=5.0, kv=0.5)
    return arm


def solve_pose(model: mujoco.MjModel, target: np.ndarray, seed: np.ndarray) -> np.ndarray:
    """Arm joints that put the paddle centre at ``target`` (m) with the hand pointing straight down."""
    data = mujoco.MjData(model)
    q = seed.copy()
    site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "paddle_centre")
    hand = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "hand_hand")
    arm = [model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, f"joint_{i}")] for i in range(1, 7)]
    joints = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, f"joint_{i}") for i in range(1, 7)]
    low = np.where(model.jnt_limited[joints], model.jnt_range[joints, 0], -np.inf)
    high = np.where(model.jnt_limited[joints], model.jnt_range[joints, 1], np.inf)
    for _ in range(2000):
        data.qpos[:] = 0.0
        data.qpos[arm] = q
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        jac_pos = np.zeros((3, model.nv))
        jac_rot = np.zeros((3, model.nv))
        mujoco.mj_jacSite(model, data, jac_pos, jac_rot, site)
        error_pos = target - data.site_xpos[site]
        # The hand's z axis should point down and its paddle lie along world x.
        rotation = data.xmat[hand].reshape(3, 3)
        error_rot = np.cross(rotation[:, 2], [0, 0, 1]) + np.cross(rotation[:, 0], [1, 0, 0])
        error = np.concatenate([error_pos, 0.3 * error_rot])
        jac = np.vstack([jac_pos, 0.3 * jac_rot])[:, arm]
        step = jac.T @ np.linalg.solve(jac @ jac.T + 1e-4 * np.eye(6), error)
        q = np.clip(q + np.clip(step, -0.2, 0.2), low, high)
        if np.linalg.norm(error) < 1e-6:
            break
    if np.linalg.norm(error_pos) > 1e-3:
        sys.exit(f"no arm pose reaches {target.tolist()} (left {np.linalg.norm(error_pos):.3g} m away)")
    return q


#: The paddle's sweep: its centre moves along +y at this height (m), between these y (m).
SWEEP_HEIGHT = 0.045
SWEEP_Y = (0.22, 0.58)
#: Times (s) of the sweep: hold the start, sweep, hold the end.
SWEEP_TIMES = (0.4, 2.6, 3.0)
#: Finger servo targets (rad): curled, out of the paddle's way.
FINGERS = (1.2, 1.2, 1.2)
#: A start of the inverse kinematics that finds the elbow-up branch (found once by random search).
IK_SEED = np.array([4.182, 2.25, 5.145, 0.071, 5.999, 1.112])


def main() -> None:
    import argparse

    parser = argparse.ArgumentParser(description="write jaco_scene.xml and jaco_motion.npz")
    parser.add_argument("--out", type=Path, default=HERE, help="folder to write them to (default: beside this script)")
    out = parser.parse_args().out
    out.mkdir(parents=True, exist_ok=True)
    spec = build_spec()
    model = spec.compile()
    ys = np.linspace(*SWEEP_Y, 13)
    poses = []
    q = IK_SEED
    for y in ys:
        q = solve_pose(model, np.array([0.0, y, SWEEP_HEIGHT]), q)
        poses.append(q.copy())
    hold, sweep_end, end = SWEEP_TIMES
    times = np.concatenate([[0.0], np.linspace(hold, sweep_end, len(ys)), [end]])
    arm = np.vstack([poses[0], poses, poses[-1]])
    ctrl = np.hstack([arm, np.tile(FINGERS, (len(times), 1))])
    start = np.concatenate([poses[0], FINGERS, [0.0, 0.3, 0.025, 1.0, 0.0, 0.0, 0.0]])
    spec.add_key(name="start", qpos=start.tolist())
    (out / "jaco_scene.xml").write_text(spec_xml(spec))
    np.savez(out / "jaco_motion.npz", time=times, ctrl=ctrl)
    print(f"wrote {out / 'jaco_scene.xml'} and {out / 'jaco_motion.npz'} ({len(times)} control rows)")


if __name__ == "__main__":
    main()
