"""Write fetch_scene.xml: the Fetch robot of Gymnasium-Robotics at its FetchPush table, pushing with a paddle.

The scene is Gymnasium-Robotics' own FetchPush model (``gymnasium_robotics/envs/assets/fetch/
push.xml``, which includes ``shared.xml`` and ``robot.xml``: floor, table, the Fetch robot and one
5 cm block of 2 kg), loaded with ``mujoco.MjSpec`` and edited:

* the base's three slide joints are removed and the base placed where FetchPush's reset puts it
  (slide0 = 0.405 m, slide1 = 0.48 m): the base is fixed;
* the gripper is driven as in Gymnasium-Robotics, by the mocap body ``robot0:mocap`` welded to
  ``robot0:gripper_link``; the weld's relative pose is set to the identity (Gymnasium-Robotics
  does this in Python at reset), so the mocap pose is the gripper's pose. The scene file moves the
  mocap body with keyframes; the arm's joints have no actuators and follow the weld;
* a paddle (a short handle between the closed fingers and a 24 cm wide blade below them) is fixed
  to the gripper link, with a site ``paddle`` at the blade's centre whose axes are the world's
  when the gripper points down (+x: the push direction);
* FetchPush's goal marker (site ``target0``) is removed and a site ``goal`` marks the goal area
  at the table's far side;
* the block ``object0`` stays as it is: the scene file copies it.

The arm's start joints are solved by inverse kinematics (mujoco's Jacobians) for the gripper at
the motion's first pose and written as the ``<key name="start">`` the scene file names. The
meshes and textures stay where pip installed gymnasium-robotics: the written model points at them
by absolute path, so run this script once after ``pip install 'energy-margin[examples]'``.

    python examples/fetch/write_model.py
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
from pathlib import Path

import mujoco
import numpy as np

from energy_margin.compat import delete_element, set_asset_dirs, spec_xml

HERE = Path(__file__).resolve().parent
#: Where FetchPush's reset puts the base (robot.xml's base position plus slide0 and slide1), m.
BASE_POS = (0.2869 + 0.405, 0.2641 + 0.48, 0.0)
#: Gripper pointing down (Gymnasium-Robotics' gripper_rotation 1 0 1 0, normalised): its x axis is
#: world -z, its z axis world +x, its y axis world +y.
GRIPPER_QUAT = (0.5**0.5, 0.0, 0.5**0.5, 0.0)
#: Blade of the paddle in the gripper frame: centre (m) and half sizes (m) along the gripper's
#: x (down), y (across the push) and z (along the push).
BLADE_POS = (0.075, 0.0, 0.0)
BLADE_HALF = (0.02, 0.12, 0.008)
#: Handle between the closed fingers, gripper frame (m).
HANDLE_POS = (0.035, 0.0, 0.0)
HANDLE_HALF = (0.025, 0.004, 0.006)
#: Torso lift joint: at its lower limit (m).
TORSO_LIFT = 0.0386
ARM_JOINTS = (
    "shoulder_pan",
    "shoulder_lift",
    "upperarm_roll",
    "elbow_flex",
    "forearm_roll",
    "wrist_flex",
    "wrist_roll",
)
#: Gripper (mocap) position at the start of the sweep, m: behind the blocks at the table's near edge.
START = (1.15, 0.75, 0.50)


def fetch_dir() -> Path:
    """The folder of the Fetch models in the installed gymnasium-robotics (without importing it)."""
    found = importlib.util.find_spec("gymnasium_robotics")
    if found is None or found.origin is None:
        sys.exit("this example needs gymnasium-robotics: pip install 'energy-margin[examples]'")
    return Path(found.origin).resolve().parent / "envs" / "assets" / "fetch"


def build_spec() -> mujoco.MjSpec:
    """FetchPush's model with the base fixed, the weld's relative pose the identity and the paddle."""
    root = fetch_dir()
    spec = mujoco.MjSpec.from_file(str(root / "push.xml"))
    spec.modelname = "fetch_scene"
    set_asset_dirs(
        spec,
        meshdir=str((root / ".." / "stls" / "fetch").resolve()),
        texturedir=str((root / ".." / "textures").resolve()),
    )
    base = spec.body("robot0:base_link")
    for name in ("robot0:slide0", "robot0:slide1", "robot0:slide2"):
        delete_element(spec, spec.joint(name))
    base.pos = list(BASE_POS)
    (weld,) = [eq for eq in spec.equalities if eq.type == mujoco.mjtEq.mjEQ_WELD]
    data = np.array(weld.data)
    data[:3] = 0.0  # anchor
    data[3:10] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]  # relative pose: identity
    weld.data = data
    gripper = spec.body("robot0:gripper_link")
    colour = [0.2, 0.5, 0.9, 1.0]
    gripper.add_geom(
        name="paddle_handle", type=mujoco.mjtGeom.mjGEOM_BOX, size=list(HANDLE_HALF), pos=list(HANDLE_POS), rgba=colour
    )
    gripper.add_geom(
        name="paddle_blade", type=mujoco.mjtGeom.mjGEOM_BOX, size=list(BLADE_HALF), pos=list(BLADE_POS), rgba=colour
    )
    # The site's frame undoes the gripper's rotation: world axes while the gripper points down.
    inverse = np.array(GRIPPER_QUAT) * [1.0, -1.0, -1.0, -1.0]
    gripper.add_site(name="paddle", pos=list(BLADE_POS), quat=inverse.tolist())
    delete_element(spec, spec.site("target0"))
    spec.worldbody.add_site(
        name="goal",
        pos=[1.475, 0.75, 0.4],
        type=mujoco.mjtGeom.mjGEOM_CYLINDER,
        size=[0.01, 0.001, 0],
        rgba=[0, 0.7, 0, 1],
    )
    return spec


def solve_start(model: mujoco.MjModel, target: np.ndarray) -> np.ndarray:
    """The qpos with the arm's joints putting the gripper link at ``target`` (m), pointing down."""
    data = mujoco.MjData(model)
    joints = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, f"robot0:{n}_joint") for n in ARM_JOINTS]
    address = model.jnt_qposadr[joints]
    dofs = model.jnt_dofadr[joints]
    low = np.where(model.jnt_limited[joints], model.jnt_range[joints, 0], -np.inf)
    high = np.where(model.jnt_limited[joints], model.jnt_range[joints, 1], np.inf)
    gripper = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "robot0:gripper_link")
    want = np.zeros(9)
    mujoco.mju_quat2Mat(want, np.array(GRIPPER_QUAT))
    want = want.reshape(3, 3)
    data.qpos[:] = model.qpos0
    data.qpos[model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "robot0:torso_lift_joint")]] = (
        TORSO_LIFT
    )
    # Elbow up: a bent shoulder and elbow as a start.
    q = np.array([0.0, 0.6, 0.0, 1.2, 0.0, 0.9, 0.0])
    for _ in range(3000):
        data.qpos[address] = q
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        jac_pos = np.zeros((3, model.nv))
        jac_rot = np.zeros((3, model.nv))
        mujoco.mj_jacBody(model, data, jac_pos, jac_rot, gripper)
        rotation = data.xmat[gripper].reshape(3, 3)
        error_pos = target - data.xpos[gripper]
        error_rot = 0.5 * sum(np.cross(rotation[:, i], want[:, i]) for i in range(3))
        error = np.concatenate([error_pos, error_rot])
        jac = np.vstack([jac_pos, jac_rot])[:, dofs]
        step = jac.T @ np.linalg.solve(jac @ jac.T + 1e-4 * np.eye(6), error)
        q = np.clip(q + np.clip(step, -0.1, 0.1), low, high)
        if np.linalg.norm(error) < 1e-7:
            break
    if np.linalg.norm(error_pos) > 1e-3 or np.linalg.norm(error_rot) > 1e-3:
        sys.exit(f"no arm pose reaches {target.tolist()} (left {np.linalg.norm(error_pos):.3g} m away)")
    data.qpos[address] = q
    return data.qpos.copy()


def main() -> None:
    """Write fetch_scene.xml (with the ``start`` key) to ``--out``."""
    parser = argparse.ArgumentParser(description="write fetch_scene.xml")
    parser.add_argument("--out", type=Path, default=HERE, help="folder to write it to (default: beside this script)")
    out = parser.parse_args().out
    out.mkdir(parents=True, exist_ok=True)
    spec = build_spec()
    model = spec.compile()
    qpos = solve_start(model, np.array(START))
    spec.add_key(name="start", qpos=qpos.tolist(), mpos=list(START), mquat=list(GRIPPER_QUAT))
    (out / "fetch_scene.xml").write_text(spec_xml(spec))
    arm = qpos[[model.jnt_qposadr[model.joint(f"robot0:{n}_joint").id] for n in ARM_JOINTS]]
    print(f"wrote {out / 'fetch_scene.xml'} (arm at the start: {np.round(arm, 3).tolist()} rad)")


if __name__ == "__main__":
    main()
