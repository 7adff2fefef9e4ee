"""Write manipulator_scene.xml: dm_control's planar manipulator carrying a cup of cubes along an arc.

The arm is dm_control's planar manipulator (dm_control/suite/manipulator.xml, with the
suite's common/ materials, skybox and visual settings): four hinges about the y axis (root,
shoulder, elbow, wrist) and a two-finger gripper, moving in the x-z plane. It is loaded with
``mujoco.MjSpec``; the suite's props (ball, peg, slot, cup, targets) are removed, its motors are
replaced by position servos (four arm joints and the gripper's grasp tendon), and a small open cup
is fixed beside the hand (the tool that carries). One cube body is the object template the scene
file copies. The script solves the arm's inverse kinematics with MuJoCo's Jacobians for the cup's
path (lifted from the floor on the left, swung along a half ellipse under the arm's base, set
down on the right, level all the way) and writes the servo targets to manipulator_motion.npz. Run it once after
``pip install 'energy-margin[examples]'``:

    python examples/planar_manipulator/write_model.py
"""

from __future__ import annotations

import sys
from pathlib import Path

import mujoco
import numpy as np

from energy_margin.compat import add_in_frame, delete_element, set_to_position, spec_xml

HERE = Path(__file__).resolve().parent
#: The suite's props, removed (the ball and peg have joints of their own).
PROPS = ("ball", "peg", "slot", "cup", "target_ball", "target_peg")
#: Position servos on the arm joints: stiffness N m/rad and force limit N m (the suite's motor gears,
#: its control range being +-1). Their damping is the joints' own (the suite's 2, 1.5, 1 and
#: 0.5 N m s/rad), which MuJoCo integrates implicitly: a velocity gain in the servo would be explicit
#: and makes these light links chatter.
ARM_JOINTS = ("arm_root", "arm_shoulder", "arm_elbow", "arm_wrist")
ARM_KP = (300.0, 200.0, 100.0, 50.0)
ARM_FORCE = (12.0, 8.0, 4.0, 2.0)
#: The gripper: a servo on the grasp tendon (the mean of the two finger angles, rad; N m/rad, N m),
#: held closed, out of the cup's way.
GRASP_TARGET = 0.5
GRASP_KP, GRASP_FORCE = 10.0, 2.0
#: The cup, in its own frame (z up, origin at the middle of its floor): inner half sizes (m), wall
#: height above the floor (m), wall thickness (m), mass (kg).
CUP_HALF = (0.05, 0.025)
CUP_WALL = 0.03
CUP_THICK = 0.01
CUP_MASS = 0.05
CUP_RGBA = [0.85, 0.85, 0.8, 1]
#: Where the cup's frame sits in the hand's frame (m): beside the fingers, its floor level with the
#: fingertips, upside down with respect to the hand so that it is level when the hand points down.
CUP_POS = (-0.11, 0.0, 0.11)
CUP_QUAT = (0.0, 0.0, 1.0, 0.0)
#: The object: a cube of this half size (m) and mass (kg).
CUBE_HALF = 0.011
CUBE_MASS = 0.02


def suite_file() -> Path:
    """dm_control's planar manipulator model, where pip installed it."""
    try:
        import dm_control
    except ImportError:
        sys.exit("this example needs dm_control: pip install 'energy-margin[examples]'")
    return Path(dm_control.__file__).resolve().parent / "suite" / "manipulator.xml"


def add_cup(hand: mujoco.MjsBody) -> None:
    """The cup's floor and four walls as geoms of the hand, and the site ``cup`` at its floor."""
    frame = hand.add_frame(pos=list(CUP_POS), quat=list(CUP_QUAT))
    hx, hy = CUP_HALF
    t, h = CUP_THICK, CUP_WALL
    # The wall next to the hand reaches up to it (the cup's handle).
    near_height = CUP_POS[2] - 0.02
    parts = {
        "cup_floor": ((0, 0, -t / 2), (hx + t, hy + t, t / 2)),
        "cup_far": ((hx + t / 2, 0, h / 2), (t / 2, hy + t, h / 2)),
        "cup_near": ((-hx - t / 2, 0, near_height / 2), (t / 2, hy + t, near_height / 2)),
        "cup_back": ((0, hy + t / 2, h / 2), (hx, t / 2, h / 2)),
        "cup_front": ((0, -hy - t / 2, h / 2), (hx, t / 2, h / 2)),
    }
    volume = {name: np.prod(half) for name, (_, half) in parts.items()}
    total = sum(volume.values())
    for name, (pos, half) in parts.items():
        add_in_frame(
            hand,
            frame,
            "geom",
            name=name,
            type=mujoco.mjtGeom.mjGEOM_BOX,
            pos=list(pos),
            size=list(half),
            mass=CUP_MASS * volume[name] / total,
            rgba=CUP_RGBA,
        )
    add_in_frame(hand, frame, "site", name="cup", pos=[0, 0, 0])
    # A bar from the hand to the handle (no contacts: it only shows what holds the cup).
    hand.add_geom(
        name="cup_bracket",
        type=mujoco.mjtGeom.mjGEOM_BOX,
        pos=[-0.034, 0, 0.022],
        size=[0.023, 0.006, 0.004],
        mass=0.005,
        contype=0,
        conaffinity=0,
        rgba=CUP_RGBA,
    )


def build_spec() -> mujoco.MjSpec:
    """The manipulator without the suite's props and motors, with servos, the cup and a cube template."""
    spec = mujoco.MjSpec.from_file(str(suite_file()))
    spec.modelname = "planar_manipulator_cup"
    # 2 ms (the suite's is 1 ms), with MuJoCo's default Euler integrator: under implicitfast the light
    # cubes' spin grew without bound in some roll-outs.
    spec.option.timestep = 0.002
    for name in PROPS:
        delete_element(spec, spec.body(name))
    for actuator in list(spec.actuators):
        delete_element(spec, actuator)
    add_cup(spec.body("hand"))
    servos = [
        (joint.removeprefix("arm_"), joint, mujoco.mjtTrn.mjTRN_JOINT, kp, force)
        for joint, kp, force in zip(ARM_JOINTS, ARM_KP, ARM_FORCE, strict=True)
    ]
    servos.append(("grasp", "grasp", mujoco.mjtTrn.mjTRN_TENDON, GRASP_KP, GRASP_FORCE))
    for name, target, transmission, kp, force in servos:
        actuator = spec.add_actuator(name=name, target=target)
        actuator.trntype = transmission
        set_to_position(actuator, kp=kp)
        actuator.ctrllimited = False
        actuator.forcelimited = True
        actuator.forcerange = [-force, force]
    world = spec.worldbody
    cube = world.add_body(name="cube", pos=[0, 0, 0.3])
    cube.add_freejoint()
    cube.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[CUBE_HALF] * 3, mass=CUBE_MASS, rgba=[0.95, 0.55, 0.15, 1])
    return spec


#: The cup's path (its floor's middle, m, in the x-z plane): from the floor at START_X along a half
#: ellipse of this height (under the arm's base, 0.4 m up) to the floor at END_X, level all the way.
START_X, END_X = -0.2, 0.25
REST_Z = CUP_THICK + 0.001
ARC_HEIGHT = 0.20
#: Times (s): hold on the floor, the arc (a minimum-jerk profile along it), the end of the roll-out.
HOLD, ARC_END, DURATION = 0.3, 1.5, 2.2
ARC_ROWS = 45
#: A start of the inverse kinematics (root, shoulder, elbow, wrist; rad): the upper arm hanging to
#: the left (found once by random search).
IK_SEED = np.array([2.0, 0.2, 0.7, 0.2])


def solve_pose(model: mujoco.MjModel, target: np.ndarray, seed: np.ndarray) -> np.ndarray:
    """Arm joints that put the cup's floor centre at ``target`` (x, z; m) with the cup level."""
    data = mujoco.MjData(model)
    site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "cup")
    joints = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name) for name in ARM_JOINTS]
    address = model.jnt_qposadr[joints]
    dofs = model.jnt_dofadr[joints]
    low = np.where(model.jnt_limited[joints], model.jnt_range[joints, 0], -np.inf)
    high = np.where(model.jnt_limited[joints], model.jnt_range[joints, 1], np.inf)
    goal = np.array([target[0], 0.0, target[1]])
    q = seed.copy()
    for _ in range(500):
        data.qpos[address] = q
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        jac_pos = np.zeros((3, model.nv))
        jac_rot = np.zeros((3, model.nv))
        mujoco.mj_jacSite(model, data, jac_pos, jac_rot, site)
        error_pos = goal - data.site_xpos[site]
        # In the plane: x and z of the position, and the rotation about y that levels the cup.
        up = data.site_xmat[site].reshape(3, 3)[:, 2]
        error = np.array([error_pos[0], error_pos[2], np.cross(up, [0, 0, 1])[1]])
        jac = np.vstack([jac_pos[0], jac_pos[2], jac_rot[1]])[:, dofs]
        # Damped least squares, with a small pull towards the previous pose (the arm is redundant).
        step = jac.T @ np.linalg.solve(jac @ jac.T + 1e-4 * np.eye(3), error)
        step += 0.05 * (np.eye(4) - np.linalg.pinv(jac) @ jac) @ (seed - q)
        q = np.clip(q + np.clip(step, -0.2, 0.2), low, high)
        if np.linalg.norm(error) < 1e-7:
            break
    if np.linalg.norm(error) > 1e-3:
        sys.exit(f"no arm pose puts the cup at {target.tolist()} (left {np.linalg.norm(error):.3g} away)")
    return q


def cup_path(n: int) -> np.ndarray:
    """``n`` points (x, z; m) of the half ellipse, evenly spaced in time under a minimum-jerk profile."""
    tau = np.linspace(0.0, 1.0, n)
    s = 10 * tau**3 - 15 * tau**4 + 6 * tau**5
    angle = np.pi * (1.0 - s)
    centre, half_width = (START_X + END_X) / 2, (END_X - START_X) / 2
    return np.stack([centre + half_width * np.cos(angle), REST_Z + ARC_HEIGHT * np.sin(angle)], axis=1)


def main() -> None:
    """Write the model, with a keyframe ``start`` (the arm at the first control row), and the motion."""
    import argparse

    parser = argparse.ArgumentParser(description="write manipulator_scene.xml and manipulator_motion.npz")
    parser.add_argument("--out", type=Path, default=HERE, help="folder to write them to (default: beside this script)")
    out = parser.parse_args().out
    out.mkdir(parents=True, exist_ok=True)
    spec = build_spec()
    model = spec.compile()
    poses = []
    q = IK_SEED
    for point in cup_path(ARC_ROWS):
        q = solve_pose(model, point, q)
        poses.append(q.copy())
    times = np.concatenate([[0.0], np.linspace(HOLD, ARC_END, ARC_ROWS), [DURATION]])
    arm = np.vstack([poses[0], poses, poses[-1]])
    ctrl = np.hstack([arm, np.full((len(times), 1), GRASP_TARGET)])
    start = np.zeros(model.nq)
    start[:4] = poses[0]
    for finger in ("thumb", "finger"):  # closed, as the grasp servo holds them
        start[model.joint(finger).qposadr[0]] = GRASP_TARGET
    start[model.nq - 7 :] = [0.0, 0.0, 0.3, 1.0, 0.0, 0.0, 0.0]
    spec.add_key(name="start", qpos=start.tolist(), ctrl=ctrl[0].tolist())
    (out / "manipulator_scene.xml").write_text(spec_xml(spec))
    np.savez(out / "manipulator_motion.npz", time=times, ctrl=ctrl)
    print(f"wrote {out / 'manipulator_scene.xml'} and {out / 'manipulator_motion.npz'} ({len(times)} control rows)")


if __name__ == "__main__":
    main()
