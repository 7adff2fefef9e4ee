"""The objects of a scene in its compiled model: which bodies, their joints, their bounds.

An object is named by a body (or a template's copies); it is the body that carries its joint
(the named body, or the one jointed body welded below a jointless named body) with every body
welded to it (:func:`~energy_margin.sim.mujoco_index.object_owners`). :func:`object_joint_kind`
reads the kind of the objects' joints from the model where the scene file does not say it;
:func:`object_joint` checks each object's joints against that kind; :func:`object_bounds` bounds
each object's geoms in its body frame, :func:`object_footprints` in the world x-y plane. Each
problem is one ``spec.error`` line naming the key.
"""

from __future__ import annotations

import fnmatch

import mujoco
import numpy as np

from energy_margin.sim.mujoco_index import object_geoms, upright_axes, world_aligned
from energy_margin.tasks.scene_spec import SceneSpec

__all__ = [
    "JOINT_KINDS",
    "element_name",
    "moving_body",
    "object_bodies",
    "object_bounds",
    "object_footprints",
    "object_joint",
    "object_joint_kind",
]

_FREE = mujoco.mjtJoint.mjJNT_FREE
_SLIDE = mujoco.mjtJoint.mjJNT_SLIDE
_HINGE = mujoco.mjtJoint.mjJNT_HINGE
JOINT_KINDS = {int(_FREE): "free", int(mujoco.mjtJoint.mjJNT_BALL): "ball", int(_SLIDE): "slide", int(_HINGE): "hinge"}


def element_name(model: mujoco.MjModel, kind: mujoco.mjtObj, index: int) -> str:
    """The name of element ``index`` of type ``kind``, or ``unnamed #INDEX``."""
    return mujoco.mj_id2name(model, kind, index) or f"unnamed #{index}"


def object_bodies(spec: SceneSpec, model: mujoco.MjModel) -> list[int]:
    """The moving body of each object, in the file's order (a template's copies, or ``objects.bodies``)."""
    names = [element_name(model, mujoco.mjtObj.mjOBJ_BODY, i) for i in range(1, model.nbody)]
    if spec.template is not None:
        return [
            mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"{spec.template}_{i}") for i in range(spec.count or 0)
        ]
    chosen: list[int] = []
    for pattern in spec.bodies or ():
        matches = [index + 1 for index, name in enumerate(names) if fnmatch.fnmatchcase(name, pattern)]
        if not matches:
            raise spec.error("objects.bodies", f"no body {pattern!r} in {spec.mjcf.name}")
        for match in matches:
            body = moving_body(spec, model, match)
            if body not in chosen:
                chosen.append(body)
    return chosen


def _jointed_descendants(model: mujoco.MjModel, body: int) -> list[int]:
    """The bodies of ``body``'s subtree that carry a joint with none between them and ``body``."""
    welded = {body}
    found: list[int] = []
    for child in range(body + 1, int(model.nbody)):
        parent = int(model.body_parentid[child])
        if parent in welded:
            (found.append if int(model.body_jntnum[child]) else welded.add)(child)
    return found


def moving_body(spec: SceneSpec, model: mujoco.MjModel, body: int) -> int:
    """The body that carries object ``body``'s joint: itself, or the one jointed body welded below it."""
    if int(model.body_jntnum[body]):
        return body
    jointed = _jointed_descendants(model, body)
    if len(jointed) == 1:
        return jointed[0]
    name = element_name(model, mujoco.mjtObj.mjOBJ_BODY, body)
    if not jointed:
        raise spec.error("objects", f"object body {name!r} in {spec.mjcf.name} has no joint: it cannot move")
    names = ", ".join(repr(element_name(model, mujoco.mjtObj.mjOBJ_BODY, b)) for b in jointed)
    raise spec.error(
        "objects",
        f"object body {name!r} in {spec.mjcf.name} has no joint of its own but several jointed children "
        f"({names}): name each of them as an object",
    )


def object_joint(spec: SceneSpec, model: mujoco.MjModel, body: int) -> int:
    """The first joint of object ``body``, checked against the scene's kind of object joints."""
    name = element_name(model, mujoco.mjtObj.mjOBJ_BODY, body)
    first, count = int(model.body_jntadr[body]), int(model.body_jntnum[body])
    kinds = [int(model.jnt_type[j]) for j in range(first, first + count)]
    described = ", ".join(
        f"{JOINT_KINDS.get(kind, '?')} {element_name(model, mujoco.mjtObj.mjOBJ_JOINT, j)!r}"
        for j, kind in zip(range(first, first + count), kinds, strict=True)
    )
    ancestor = int(model.body_parentid[body])
    while ancestor:
        if int(model.body_jntnum[ancestor]):
            moving = element_name(model, mujoco.mjtObj.mjOBJ_BODY, ancestor)
            raise spec.error("objects", f"object body {name!r} rides on body {moving!r}, which has a joint")
        ancestor = int(model.body_parentid[ancestor])
    if spec.object_joints == "free":
        if kinds != [int(_FREE)]:
            raise spec.error(
                "objects.joints",
                f"body {name!r} in {spec.mjcf.name} is not free (joints: {described or 'none'}); "
                "give it a <freejoint/> or set objects.joints = 'upright' for slide x, y, z and hinge z",
            )
        return first
    if not world_aligned(model, body):
        raise spec.error(
            "objects.joints",
            f"upright body {name!r} in {spec.mjcf.name} must not be rotated (quat 1 0 0 0, and its holders too): "
            "its slide joints then move it along the world axes",
        )
    if not kinds or upright_axes(model, body) is None:
        raise spec.error(
            "objects.joints",
            f"body {name!r} in {spec.mjcf.name} does not have upright joints: slide x, slide y, slide z and "
            f"hinge z, or some of them, one per axis (joints: {described or 'none'})",
        )
    return first


def object_joint_kind(model: mujoco.MjModel, bodies: list[int] | np.ndarray) -> str:
    """``"free"`` when any of ``bodies`` (the objects' moving bodies) has a free joint, else ``"upright"``.

    What a scene file without ``objects.joints`` gets; a body whose joints are not of that kind
    is refused when the scene is resolved, naming its joints.
    """
    free = [
        int(model.body_jntnum[body]) == 1 and int(model.jnt_type[model.body_jntadr[body]]) == int(_FREE)
        for body in bodies
    ]
    return "free" if any(free) else "upright"


def object_bounds(spec: SceneSpec, model: mujoco.MjModel, bodies: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """Bounding radius (n,) and box half extents (n, 3) of each object's geoms in its body frame, m.

    The geoms are those of the object's rigid subtree (:func:`~energy_margin.sim.mujoco_index.object_geoms`);
    a geom on a welded child body is placed by the model's reference configuration.
    """
    radius = np.zeros(len(bodies))
    extents = np.zeros((len(bodies), 3))
    kinematics: mujoco.MjData | None = None
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    for index, (body, geoms) in enumerate(zip(bodies, object_geoms(model, bodies), strict=True)):
        if geoms.size == 0:
            raise spec.error("objects", f"object {element_name(model, mujoco.mjtObj.mjOBJ_BODY, body)!r} has no geom")
        corners, positions = [], []
        for geom in geoms:
            flat = np.empty(9)
            if int(model.geom_bodyid[geom]) == body:
                position = np.array(model.geom_pos[geom])
                mujoco.mju_quat2Mat(flat, model.geom_quat[geom])
                matrix = flat.reshape(3, 3)
            else:
                if kinematics is None:
                    kinematics = mujoco.MjData(model)
                    mujoco.mj_kinematics(model, kinematics)
                frame = kinematics.xmat[body].reshape(3, 3)
                position = frame.T @ (kinematics.geom_xpos[geom] - kinematics.xpos[body])
                matrix = frame.T @ kinematics.geom_xmat[geom].reshape(3, 3)
            positions.append(position)
            # geom_aabb: centre (3) and half sizes (3) in each geom's frame; bound them in the body frame.
            centre, half = model.geom_aabb[geom, :3], model.geom_aabb[geom, 3:]
            corners.append(position + (centre + signs * half) @ matrix.T)
        radius[index] = float(np.max(np.linalg.norm(np.array(positions), axis=1) + model.geom_rbound[geoms]))
        extents[index] = np.max(np.abs(np.concatenate(corners)), axis=0)
    return radius, extents


def _horizontal_reach(model: mujoco.MjModel, geom: int, centre: np.ndarray, rotation: np.ndarray) -> float:
    """How far geom ``geom`` reaches from the body's vertical axis, m: its largest x-y distance from it.

    ``centre`` (3,) is the geom's centre relative to the body origin and ``rotation`` (3, 3) its
    orientation, both in world axes. Exact for boxes, spheres and a capsule or cylinder standing
    upright; an upper bound otherwise (a tilted capsule or cylinder: its axis' ends plus the
    radius; an ellipsoid: its box; a mesh or any other geom: the box of its bounding box).
    """
    kind = int(model.geom_type[geom])
    size = model.geom_size[geom]
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    if kind == int(mujoco.mjtGeom.mjGEOM_SPHERE):
        return float(np.linalg.norm(centre[:2]) + size[0])
    if kind in (int(mujoco.mjtGeom.mjGEOM_CAPSULE), int(mujoco.mjtGeom.mjGEOM_CYLINDER)):
        ends = centre + np.outer((-size[1], size[1]), rotation[:, 2])
        return float(np.max(np.linalg.norm(ends[:, :2], axis=1)) + size[0])
    if kind in (int(mujoco.mjtGeom.mjGEOM_BOX), int(mujoco.mjtGeom.mjGEOM_ELLIPSOID)):
        corners = centre + (signs * size[:3]) @ rotation.T
    else:
        box_centre, half = model.geom_aabb[geom, :3], model.geom_aabb[geom, 3:]
        corners = centre + (box_centre + signs * half) @ rotation.T
    return float(np.max(np.linalg.norm(corners[:, :2], axis=1)))


def object_footprints(model: mujoco.MjModel, bodies: np.ndarray, qpos: np.ndarray) -> np.ndarray:
    """Footprint radius of each object in the world x-y plane at configuration ``qpos``, shape (n,), m.

    The largest x-y distance of the object's geoms from the vertical line through its body origin,
    in the orientation ``qpos`` gives it: a rotation about world z (a start's yaw) keeps it, and two
    objects whose origins lie farther apart in x-y than the sum of their footprints cannot overlap,
    whatever their heights. A 12 cm can of radius 3.3 cm standing upright has 0.033 m; its bounding
    radius is 0.069 m.
    """
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    result = np.zeros(len(bodies))
    for index, (body, geoms) in enumerate(zip(bodies, object_geoms(model, bodies), strict=True)):
        origin = data.xpos[body]
        result[index] = max(
            _horizontal_reach(model, int(geom), data.geom_xpos[geom] - origin, data.geom_xmat[geom].reshape(3, 3))
            for geom in geoms
        )
    return result
