"""The MjSpec model of a scene: pinned to the model the MJCF text of earlier releases compiled to.

``build_model`` replaced a builder that formatted MJCF text; every numeric array, every name and
the binary model (``mj_saveModel``) of the built-in scenes were byte-identical between the two,
which is what keeps the pinned scores (``tests/test_pinned_scores.py``) bit-identical. The hashes
below pin that model: a change to the builder that alters anything in it (a default, an order,
a collision bit) fails here first. The authored arrays are copies of the scene's numbers, the
same on every platform; the binary model also holds what the compiler derives from them, pinned
for MuJoCo 4.0.0 on x86-64.
"""

from __future__ import annotations

import dataclasses
import hashlib
import platform
from collections.abc import Callable

import mujoco
import numpy as np
import pytest

from energy_margin.sim.mujoco_spec import BODIES, FLOOR, build_model, build_spec, spin_friction
from energy_margin.tasks import PushingTask, ScoopingTask, get_task
from energy_margin.world.scene import Geom, Joint, Link, Scene

# The arrays build_model copies from the scene (no compiler arithmetic), hashed in this order.
AUTHORED = (
    "body_parentid",
    "body_pos",
    "body_mass",
    "body_inertia",
    "body_ipos",
    "body_iquat",
    "body_gravcomp",
    "jnt_type",
    "jnt_bodyid",
    "jnt_axis",
    "jnt_range",
    "jnt_limited",
    "jnt_stiffness",
    "dof_damping",
    "dof_frictionloss",
    "geom_type",
    "geom_bodyid",
    "geom_size",
    "geom_pos",
    "geom_quat",
    "geom_friction",
    "geom_contype",
    "geom_conaffinity",
    "geom_condim",
    "geom_group",
    "geom_rgba",
    "geom_solref",
    "actuator_trntype",
    "actuator_trnid",
    "actuator_gaintype",
    "actuator_biastype",
    "actuator_gainprm",
    "actuator_biasprm",
    "actuator_forcelimited",
    "actuator_forcerange",
    "exclude_signature",
)


def _scenes() -> dict[str, Scene]:
    fast = get_task("pushing", {"ground_contact": "footprint", "lateral_contact": "sphere"})
    return {
        "pushing-3": PushingTask().build_scene(3, 0.3),
        "pushing-10-fast": fast.build_scene(10, 0.25),
        "scooping-3": ScoopingTask().build_scene(3, 0.4),
        "scooping-1-drive": ScoopingTask().build_scene(1, 0.5, np.array([1.3])),
    }


def authored_hash(model: mujoco.MjModel) -> str:
    digest = hashlib.sha256()
    for name in AUTHORED:
        array = np.ascontiguousarray(getattr(model, name))
        if name.endswith("limited"):
            array = array.astype(bool)  # uint8 before MuJoCo 3.4-ish, bool after: the same flags
        digest.update(f"{name}{array.dtype}{array.shape}".encode())
        digest.update(array.tobytes())
    for value in (model.opt.timestep, *model.opt.gravity, float(model.opt.integrator)):
        digest.update(np.float64(value).tobytes())
    digest.update(model.names)
    return digest.hexdigest()


def binary_hash(model: mujoco.MjModel) -> str:
    buffer = np.zeros(mujoco.mj_sizeModel(model), dtype=np.uint8)
    mujoco.mj_saveModel(model, None, buffer)
    return hashlib.sha256(buffer.tobytes()).hexdigest()


AUTHORED_HASHES = {
    "pushing-3": "d6c57c36eeae18561367b06c72b482ee052bf6800e3f8a47dffb1de515ee2770",
    "pushing-10-fast": "7219333530b594b4de231bbf1344fdeea7db2a81909179f1d9301e72999ad15c",
    "scooping-3": "c45045d2f8ad01675f042082a4b35e45df65bfafa6dfd394cb2caed1b522d74e",
    "scooping-1-drive": "564733f709ddae3f4ae655c579ab5ec90ac32f129c4e041c2d8555087fa7116e",
}
BINARY_HASHES = {
    "pushing-3": "671a6d8dc4d9e58b2320b40cef0f55504ed4c9823357f1afb24e76a269d3dec6",
    "pushing-10-fast": "90b6b8589c0c8505b004dbf7f9e6153863f6318b1562bfeca11a406f254d9a02",
    "scooping-3": "c19cbf0779610d4ba08d327d2056f5892655be827a6fb32bfa8ede52293820a0",
    "scooping-1-drive": "f52fa7732f0aac3406b96c8804f4ab4b413fcfd9e91afd5fe3936a72ce20fb55",
}


@pytest.mark.parametrize("label", sorted(AUTHORED_HASHES))
def test_the_authored_arrays_are_pinned(label: str) -> None:
    assert authored_hash(build_model(_scenes()[label])) == AUTHORED_HASHES[label]


@pytest.mark.skipif(
    platform.machine() not in ("x86_64", "AMD64") or mujoco.__version__ != "4.0.0",
    reason="the compiled model's derived arrays are pinned for MuJoCo 4.0.0 on x86-64",
)
@pytest.mark.parametrize("label", sorted(BINARY_HASHES))
def test_the_binary_model_is_pinned(label: str) -> None:
    assert binary_hash(build_model(_scenes()[label])) == BINARY_HASHES[label]


def _id(model: mujoco.MjModel, kind: mujoco.mjtObj, name: str) -> int:
    index = int(mujoco.mj_name2id(model, kind, name))
    assert index >= 0, name
    return index


def _every_link(scene: Scene) -> list[Link]:
    return scene.robot.iter_links() if scene.robot is not None else []


@pytest.mark.parametrize("label", sorted(AUTHORED_HASHES))
def test_the_model_is_the_scenes(label: str) -> None:
    scene = _scenes()[label]
    model = build_model(scene)
    assert model.opt.timestep == scene.timestep
    np.testing.assert_array_equal(model.opt.gravity, scene.gravity)
    integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST if scene.integrator == "implicitfast" else 0
    assert model.opt.integrator == integrator
    assert model.opt.cone == mujoco.mjtCone.mjCONE_PYRAMIDAL
    assert model.opt.solver == mujoco.mjtSolver.mjSOL_NEWTON
    # Sliding friction only, the scene's coefficient on every geom.
    np.testing.assert_array_equal(model.geom_condim, 3)
    np.testing.assert_array_equal(model.geom_friction, np.tile([scene.friction, 0.0, 0.0], (model.ngeom, 1)))
    solref = [scene.contact_time_constant, 1.0] if scene.contact_time_constant is not None else [0.02, 1.0]
    np.testing.assert_array_equal(model.geom_solref, np.tile(solref, (model.ngeom, 1)))
    for obj in scene.objects:
        body = _id(model, mujoco.mjtObj.mjOBJ_BODY, obj.name)
        assert model.body_mass[body] == obj.mass
        np.testing.assert_array_equal(model.body_inertia[body], obj.inertia)
        geom = _id(model, mujoco.mjtObj.mjOBJ_GEOM, obj.name)
        assert model.geom_bodyid[geom] == body
        np.testing.assert_array_equal(model.geom_size[geom, : len(obj.geom.size)], obj.geom.size)
    for index, geom in enumerate(scene.statics):
        found = _id(model, mujoco.mjtObj.mjOBJ_GEOM, geom.name or f"static{index}")
        assert model.geom_bodyid[found] == 0
        np.testing.assert_array_equal(model.geom_size[found, : len(geom.size)], geom.size)
        np.testing.assert_array_equal(model.geom_pos[found], geom.pos)
    for link in _every_link(scene):
        body = _id(model, mujoco.mjtObj.mjOBJ_BODY, link.name)
        assert model.body_mass[body] == link.mass
        assert model.body_gravcomp[body] == (1.0 if link.gravity_compensation else 0.0)
        for joint in link.joints:
            found = _id(model, mujoco.mjtObj.mjOBJ_JOINT, joint.name)
            dof = model.jnt_dofadr[found]
            assert model.jnt_bodyid[found] == body
            assert model.dof_damping[dof] == joint.damping
            assert model.jnt_stiffness[found] == joint.stiffness
            assert bool(model.jnt_limited[found]) == (joint.limits is not None)
            if joint.limits is not None:
                np.testing.assert_array_equal(model.jnt_range[found], joint.limits)
    excluded = [link for link in _every_link(scene) if not link.collides_with_statics]
    assert model.nexclude == len(excluded)
    servoed = [joint for joint in scene.robot_joints if joint.servoed]
    assert model.nu == len(servoed)
    for joint in servoed:
        actuator = _id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, joint.name + "_servo")
        assert model.actuator_trnid[actuator, 0] == _id(model, mujoco.mjtObj.mjOBJ_JOINT, joint.name)
        assert model.actuator_gainprm[actuator, 0] == joint.servo_stiffness
        np.testing.assert_array_equal(
            model.actuator_biasprm[actuator, :3], [0.0, -joint.servo_stiffness, -joint.servo_damping]
        )
        limited = joint.force_limit is not None
        assert bool(model.actuator_forcelimited[actuator]) == limited
        if joint.force_limit is not None:
            np.testing.assert_array_equal(model.actuator_forcerange[actuator], [-joint.force_limit, joint.force_limit])


def test_footprints_and_spheres_take_the_contacts() -> None:
    scene = _scenes()["pushing-10-fast"]
    model = build_model(scene)
    ground = _id(model, mujoco.mjtObj.mjOBJ_GEOM, "ground")
    assert (model.geom_contype[ground], model.geom_conaffinity[ground]) == (FLOOR, 0)
    for obj in scene.objects:
        own = _id(model, mujoco.mjtObj.mjOBJ_GEOM, obj.name)
        sphere = _id(model, mujoco.mjtObj.mjOBJ_GEOM, obj.name + "_sphere")
        footprint = _id(model, mujoco.mjtObj.mjOBJ_GEOM, obj.name + "_footprint")
        # The cylinder itself touches nothing; its sphere the other bodies, its footprint the floor.
        assert (model.geom_contype[own], model.geom_conaffinity[own]) == (0, 0)
        assert (model.geom_contype[sphere], model.geom_conaffinity[sphere]) == (BODIES, BODIES)
        assert model.geom_size[sphere, 0] == obj.geom.size[0]
        assert (model.geom_contype[footprint], model.geom_conaffinity[footprint]) == (0, FLOOR)
        yaw = _id(model, mujoco.mjtObj.mjOBJ_JOINT, obj.name + "_yaw")
        assert model.dof_frictionloss[model.jnt_dofadr[yaw]] == spin_friction(scene, obj)
    pusher = _id(model, mujoco.mjtObj.mjOBJ_GEOM, "pusher")
    assert model.geom_conaffinity[pusher] == BODIES | FLOOR


def test_every_branch_of_the_builder(make_block_scene: Callable[..., Scene]) -> None:
    tip = Link(
        "tip",
        (Geom("sphere", (0.01,)),),
        0.05,
        pos=(0.1, 0, 0),
        joints=(Joint("t", "hinge", (0, 0, 1), servo_stiffness=3.0, servo_damping=0.2),),
        gravity_compensation=True,
        collides_with_statics=False,
    )
    arm = Link(
        "arm",
        (Geom("box", (0.05, 0.01, 0.01)),),
        0.5,
        joints=(
            Joint("a", "slide", (1, 0, 0), limits=(-1.0, 1.0), stiffness=2.0, servo_stiffness=7.0, force_limit=4.0),
        ),
        children=(tip,),
    )
    base = make_block_scene(2, shape="box", motion="upright")
    scene = dataclasses.replace(
        base, robot=arm, integrator="implicitfast", contact_time_constant=0.05, ground_contact="footprint"
    )
    model = build_model(scene)
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    assert model.nexclude == 1 and model.nu == 2
    # A box gets a footprint (no sphere stand-in: that is for cylinders).
    assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "object0_footprint") >= 0
    assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "object0_sphere") == -1
    # Unnamed link geoms are named after their link.
    assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "tip_geom0") >= 0
    spec = build_spec(scene)
    assert spec.modelname == "energy_margin"
    assert not spec.compiler.degree
