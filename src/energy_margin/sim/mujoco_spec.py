"""The MuJoCo model of a :class:`~energy_margin.world.scene.Scene`, built with ``mujoco.MjSpec``.

Contacts use MuJoCo's defaults (Newton solver, pyramidal friction cone, Euler integrator) with
``condim = 3`` (sliding friction only) and every geom's sliding friction set to the scene's
coefficient, so the contact coefficient (MuJoCo takes the larger of the two geoms') equals it.
A scene may choose the ``implicitfast`` integrator and the contact time constant. Servoed joints
get one general position actuator each (force ``kp (target - q) - kv qdot``, clamped to the
joint's force limit), in the order of the end-effector joints, named ``<joint>_servo``; links with
gravity compensation get ``gravcomp = 1``, and links that do not collide with the statics get a
contact exclusion against the world body. Objects are bodies named after
:attr:`~energy_margin.world.scene.RigidObject.name` with a free joint of that name, or with the
upright joints ``<name>_x``, ``_y``, ``_z`` (slides) and ``_yaw`` (hinge), in that order.
"""

from __future__ import annotations

import hashlib

import mujoco
import numpy as np

from energy_margin.compat import joint_coefficient
from energy_margin.errors import InvalidDataError
from energy_margin.sim.mujoco_index import ModelIndex, name_id
from energy_margin.world.scene import Geom, Link, RigidObject, Scene

__all__ = [
    "BODIES",
    "FLOOR",
    "MODEL_NAME",
    "UPRIGHT_JOINTS",
    "base_radius",
    "build_model",
    "build_spec",
    "is_floor",
    "model_hash",
    "scene_index",
    "spin_friction",
]

#: The model's name.
MODEL_NAME = "energy_margin"

# Joints of an upright object, in qpos order: position x, y, z then yaw.
UPRIGHT_JOINTS: tuple[tuple[str, mujoco.mjtJoint, tuple[float, float, float]], ...] = (
    ("_x", mujoco.mjtJoint.mjJNT_SLIDE, (1.0, 0.0, 0.0)),
    ("_y", mujoco.mjtJoint.mjJNT_SLIDE, (0.0, 1.0, 0.0)),
    ("_z", mujoco.mjtJoint.mjJNT_SLIDE, (0.0, 0.0, 1.0)),
    ("_yaw", mujoco.mjtJoint.mjJNT_HINGE, (0.0, 0.0, 1.0)),
)

_GEOM_TYPES = {
    "box": mujoco.mjtGeom.mjGEOM_BOX,
    "cylinder": mujoco.mjtGeom.mjGEOM_CYLINDER,
    "sphere": mujoco.mjtGeom.mjGEOM_SPHERE,
    "plane": mujoco.mjtGeom.mjGEOM_PLANE,
}
_JOINT_TYPES = {"slide": mujoco.mjtJoint.mjJNT_SLIDE, "hinge": mujoco.mjtJoint.mjJNT_HINGE}
_INTEGRATORS = {"Euler": mujoco.mjtIntegrator.mjINT_EULER, "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST}

# Collision bits: ordinary geoms have contype = conaffinity = BODIES. With footprints or sphere
# stand-ins a floor plane only emits FLOOR, which footprints, robot links and objects without a
# footprint accept; a cylinder's sphere emits BODIES and accepts only BODIES, never FLOOR, and
# the cylinder itself then keeps only the floor.
BODIES = 1
FLOOR = 2
# Geom group of the invisible contact helpers (footprints, sphere stand-ins).
_HELPER_GROUP = 3
_INVISIBLE = (0.0, 0.0, 0.0, 0.0)


def _add_geom(
    body: mujoco.MjsBody,
    geom: Geom,
    name: str,
    *,
    contype: int | None = None,
    conaffinity: int | None = None,
) -> mujoco.MjsGeom:
    """Add ``geom`` to ``body``; collision bits other than ``None`` replace the defaults."""
    size = [float(s) for s in geom.size]
    if geom.shape == "plane":
        size.append(0.1)  # the grid spacing MuJoCo draws a plane with
    added = body.add_geom(
        name=name,
        type=_GEOM_TYPES[geom.shape],
        size=size + [0.0] * (3 - len(size)),
        pos=[float(v) for v in geom.pos],
        quat=[float(v) for v in geom.quat],
        rgba=[float(v) for v in geom.rgba],
    )
    if contype is not None:
        added.contype = contype
    if conaffinity is not None:
        added.conaffinity = conaffinity
    return added


def _add_helper_sphere(body: mujoco.MjsBody, name: str, radius: float, pos: tuple[float, float, float]) -> None:
    body.add_geom(
        name=name,
        type=mujoco.mjtGeom.mjGEOM_SPHERE,
        size=[radius, 0.0, 0.0],
        pos=list(pos),
        group=_HELPER_GROUP,
        rgba=list(_INVISIBLE),
    )


def is_floor(geom: Geom) -> bool:
    """Whether ``geom`` is a plane whose normal is the world +z axis."""
    if geom.shape != "plane":
        return False
    _, x, y, _ = geom.quat
    # The plane's normal is its local z axis rotated by the quaternion.
    normal_z = 1.0 - 2.0 * (x * x + y * y)
    return normal_z > 1.0 - 1e-9


def base_radius(geom: Geom) -> float | None:
    """Distance from the centre of an upright shape's flat base to its rim contacts, m."""
    if geom.shape == "cylinder":
        return float(geom.size[0])
    if geom.shape == "box":
        return float(np.hypot(geom.size[0], geom.size[1]))
    return None


def spin_friction(scene: Scene, obj: RigidObject) -> float | None:
    """Dry friction of an upright object's yaw joint: the spin resistance of its rim contacts, N m.

    Rim contacts carrying the weight m g at the base radius r resist spinning with a torque up to
    mu m g r; the footprint's single point cannot, so the yaw joint gets it as ``frictionloss``,
    independent of the sliding friction (as the rim's is, to first order). ``None`` for a shape
    without a flat base.
    """
    rim = base_radius(obj.geom)
    if rim is None:
        return None
    weight = obj.mass * float(np.linalg.norm(scene.gravity))
    return scene.friction * weight * rim


def _add_footprint(body: mujoco.MjsBody, name: str, geom: Geom) -> None:
    """The base-centre contact of an upright object with the floor (see ``Scene.ground_contact``)."""
    rim = base_radius(geom)
    if rim is None:
        return
    half_height = float(geom.size[-1])
    # A small sphere touching the base's centre: one contact point at the same height as the base.
    radius = min(0.25 * rim, half_height)
    _add_helper_sphere(body, name + "_footprint", radius, (0.0, 0.0, -half_height + radius))
    footprint = body.geoms[-1]
    footprint.contype = 0
    footprint.conaffinity = FLOOR


def _add_object_geoms(body: mujoco.MjsBody, scene: Scene, obj: RigidObject, *, split_floor: bool) -> None:
    """An object's own geom, its sphere stand-in and its footprint (see ``Scene``)."""
    footprint = scene.ground_contact == "footprint" and base_radius(obj.geom) is not None
    floor = 0 if footprint or not split_floor else FLOOR
    if scene.lateral_contact == "sphere" and obj.geom.shape == "cylinder":
        # In the plane of the centres the sphere is the cylinder's circle: every contact of that
        # plane (another upright cylinder, a vertical face of the robot or a wall) has the
        # cylinder's point, normal and depth. (Against a face the engine reports the cylinder's
        # line contact as identical rows, two in MuJoCo 4.0; the sphere gives one.)
        _add_geom(body, obj.geom, obj.name, contype=0, conaffinity=floor)
        _add_helper_sphere(body, obj.name + "_sphere", float(obj.geom.size[0]), (0.0, 0.0, 0.0))
        stand_in = body.geoms[-1]
        stand_in.contype = BODIES
        stand_in.conaffinity = BODIES
    else:
        _add_geom(body, obj.geom, obj.name, conaffinity=(BODIES | floor) if floor else None)
    if footprint:
        _add_footprint(body, obj.name, obj.geom)


def _add_link(parent: mujoco.MjsBody, link: Link, conaffinity: int | None) -> None:
    body = parent.add_body(name=link.name, pos=[float(v) for v in link.pos])
    if link.gravity_compensation:
        body.gravcomp = 1.0
    for joint in link.joints:
        added = body.add_joint(
            name=joint.name,
            type=_JOINT_TYPES[joint.kind],
            axis=[float(v) for v in joint.axis],
            damping=joint_coefficient(joint.damping),
            stiffness=joint_coefficient(joint.stiffness),
        )
        if joint.limits is not None:
            added.range = [float(v) for v in joint.limits]
            added.limited = mujoco.mjtLimited.mjLIMITED_TRUE
    solid = link.inertia_geom
    _set_inertial(body, link.mass, solid.principal_inertia(link.mass), solid.pos, solid.quat)
    for index, geom in enumerate(link.geoms):
        _add_geom(body, geom, geom.name or f"{link.name}_geom{index}", conaffinity=conaffinity)
    for child in link.children:
        _add_link(body, child, conaffinity)


def _set_inertial(
    body: mujoco.MjsBody,
    mass: float,
    inertia: tuple[float, float, float],
    pos: tuple[float, float, float] = (0.0, 0.0, 0.0),
    quat: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0),
) -> None:
    """Give ``body`` an explicit inertial frame (its geoms then carry no mass)."""
    body.explicitinertial = True
    body.mass = float(mass)
    body.inertia = [float(v) for v in inertia]
    body.ipos = [float(v) for v in pos]
    body.iquat = [float(v) for v in quat]


def _add_object(spec: mujoco.MjSpec, scene: Scene, obj: RigidObject, *, split_floor: bool) -> None:
    if obj.geom.pos != (0.0, 0.0, 0.0) or obj.geom.quat != (1.0, 0.0, 0.0, 0.0):
        raise InvalidDataError(f"object {obj.name!r}: its geom must be centred at the body origin")
    body = spec.worldbody.add_body(name=obj.name)
    if scene.object_motion == "free":
        body.add_freejoint(name=obj.name)
    else:
        for suffix, kind, axis in UPRIGHT_JOINTS:
            joint = body.add_joint(name=obj.name + suffix, type=kind, axis=list(axis))
            friction = spin_friction(scene, obj) if suffix == "_yaw" and scene.ground_contact == "footprint" else None
            if friction is not None:
                joint.frictionloss = friction
    _set_inertial(body, obj.mass, obj.inertia)
    _add_object_geoms(body, scene, obj, split_floor=split_floor)


def _add_servos(spec: mujoco.MjSpec, scene: Scene) -> None:
    """One position servo per servoed end-effector joint (a general actuator, affine bias)."""
    for joint in scene.robot_joints:
        if joint.servo_stiffness is None:
            continue
        kp, kv = float(joint.servo_stiffness), float(joint.servo_damping)
        actuator = spec.add_actuator(
            name=joint.name + "_servo",
            target=joint.name,
            trntype=mujoco.mjtTrn.mjTRN_JOINT,
            gaintype=mujoco.mjtGain.mjGAIN_FIXED,
            biastype=mujoco.mjtBias.mjBIAS_AFFINE,
        )
        actuator.gainprm[0] = kp
        actuator.biasprm[:3] = [0.0, -kp, -kv]
        if joint.force_limit is not None:
            actuator.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
            actuator.forcerange = [-float(joint.force_limit), float(joint.force_limit)]


def build_spec(scene: Scene) -> mujoco.MjSpec:
    """The uncompiled model of ``scene`` (see the module's description).

    Raises:
        InvalidDataError: an object's geom is not centred at its body origin.

    """
    spec = mujoco.MjSpec()
    spec.modelname = MODEL_NAME
    spec.compiler.degree = False
    spec.option.timestep = float(scene.timestep)
    spec.option.gravity = [float(g) for g in scene.gravity]
    spec.option.integrator = _INTEGRATORS[scene.integrator]
    # Defaults first: an element takes them when it is added.
    spec.default.geom.condim = 3
    spec.default.geom.friction = [float(scene.friction), 0.0, 0.0]
    if scene.contact_time_constant is not None:
        spec.default.geom.solref = [float(scene.contact_time_constant), 1.0]
    # Footprints and lateral stand-ins need the floor on its own collision bit.
    split_floor = scene.ground_contact == "footprint" or scene.lateral_contact == "sphere"
    for index, geom in enumerate(scene.statics):
        floor = split_floor and is_floor(geom)
        _add_geom(
            spec.worldbody,
            geom,
            geom.name or f"static{index}",
            contype=FLOOR if floor else None,
            conaffinity=0 if floor else None,
        )
    if scene.robot is not None:
        # Robot links keep touching the floor through their own shapes.
        _add_link(spec.worldbody, scene.robot, (BODIES | FLOOR) if split_floor else None)
    for obj in scene.objects:
        _add_object(spec, scene, obj, split_floor=split_floor)
    for link in scene.robot_links:
        if not link.collides_with_statics:
            spec.add_exclude(bodyname1="world", bodyname2=link.name)
    _add_servos(spec, scene)
    return spec


def build_model(scene: Scene) -> mujoco.MjModel:
    """The compiled model of ``scene``."""
    return build_spec(scene).compile()


def model_hash(model: mujoco.MjModel) -> str:
    """SHA-256 of a compiled model in MuJoCo's binary format (MJB): equal models, equal hashes."""
    buffer = np.zeros(mujoco.mj_sizeModel(model), dtype=np.uint8)
    mujoco.mj_saveModel(model, None, buffer)
    return hashlib.sha256(buffer.tobytes()).hexdigest()


def scene_index(model: mujoco.MjModel, scene: Scene) -> ModelIndex:
    """The addresses of ``scene``'s objects and robot in ``model``, its compiled model, by name."""
    first_joint = UPRIGHT_JOINTS[0][0] if scene.object_motion == "upright" else ""
    return ModelIndex.of(
        model,
        scene,
        object_joints=[name_id(model, mujoco.mjtObj.mjOBJ_JOINT, obj.name + first_joint) for obj in scene.objects],
        robot_joints=[name_id(model, mujoco.mjtObj.mjOBJ_JOINT, name) for name in scene.robot_joint_names],
        servoed=[joint.servoed for joint in scene.robot_joints],
        servo_actuators=[
            name_id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, joint.name + "_servo")
            for joint in scene.robot_joints
            if joint.servoed
        ],
    )
