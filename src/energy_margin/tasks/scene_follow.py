"""Whether a scene's capture and success regions follow the robot: from the model's kinematic tree.

A region table names bodies, sites and geoms (``body = "paddle"``, ``site = "tip"``). A region
attached to an element whose body is moved by the robot (the body, or one of its ancestors, has a
robot joint an actuator drives, is a mocap body or is welded to one, :func:`robot_mover`) moves on
with the robot in every state of a tree; by default it then *follows* it: it is built at each
state's own robot configuration. A region attached to nothing, or only to bodies the robot does
not move, is fixed in the world (or at the analysed frame, for an object's body) as before.
``capture.follow`` and ``success.follow`` in the file decide instead (``follow = false`` freezes a
moving region at the analysed frame).
"""

from __future__ import annotations

from collections.abc import Collection, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from energy_margin.tasks.scene_sections import region_names
from energy_margin.world.state import FrameState

__all__ = ["Anchor", "RegionFollow", "node_frames", "region_follow", "robot_mover"]

_KINDS = {"body": mujoco.mjtObj.mjOBJ_BODY, "site": mujoco.mjtObj.mjOBJ_SITE, "geom": mujoco.mjtObj.mjOBJ_GEOM}


@dataclass(frozen=True)
class Anchor:
    """A model element a region table names, and what moves it.

    Attributes:
        kind: ``"body"``, ``"site"`` or ``"geom"``.
        name: the element's name.
        key: its key in the scene file, e.g. ``"capture.region.of[0].site"``.
        body: the name of the body the element belongs to.
        mover: what moves that body with the robot, e.g. ``"joint 'wrist'"`` or ``"mocap body
            'pusher'"``, or ``None`` when the robot does not move it.
        static: the body is fixed to the world (no joint up its kinematic tree, not a mocap body).

    """

    kind: str
    name: str
    key: str
    body: str
    mover: str | None
    static: bool = False


@dataclass(frozen=True)
class RegionFollow:
    """Whether a set's region follows the robot, whether the file says so, and why.

    Attributes:
        name: ``"capture"`` or ``"success"``.
        follows: the region is built at every tree state's own robot configuration.
        stated: the file writes ``NAME.follow`` (else ``follows`` is the default of its anchors).
        anchors: the elements the region is attached to.
        placed_by_objects: an object's joint lies between an anchor and the world (else the
            anchors' poses are the same whatever the objects' coordinates, and the region is built
            without them).

    """

    name: str
    follows: bool
    stated: bool
    anchors: tuple[Anchor, ...]
    placed_by_objects: bool = True

    @property
    def moving(self) -> tuple[Anchor, ...]:
        """The anchors the robot moves."""
        return tuple(anchor for anchor in self.anchors if anchor.mover is not None)

    def describe(self) -> str:
        """``follows the robot (attached to body 'paddle', moved by joint 'wrist')``, marked ``(default)``."""
        moving = self.moving
        attached = "; ".join(f"attached to body {a.body!r}, moved by {a.mover}" for a in moving)
        if self.follows:
            why = attached if moving else "follow = true; attached to no body the robot moves"
            text = f"follows the robot ({why})"
        elif moving:
            text = f"fixed at the analysed frame (follow = false; {attached})"
        elif any(not anchor.static for anchor in self.anchors):
            bodies = ", ".join(sorted({repr(a.body) for a in self.anchors if not a.static}))
            text = f"fixed at the analysed frame (attached to body {bodies}, which the robot does not move)"
        else:
            text = "fixed in the world"
        return text if self.stated else f"{text} (default)"


def robot_mover(model: mujoco.MjModel, body: int, robot_joints: Sequence[int]) -> str | None:
    """What moves ``body`` with the robot: the nearest driver up its kinematic tree, or ``None``.

    Walking from ``body`` to the world, the first of: a mocap body; a body welded (or connected) to
    a mocap body by an equality constraint; a body an actuator's site is on; a body with a robot
    joint (of ``robot_joints``) that an actuator drives, directly or through a tendon, or below
    which a body is welded to a mocap body (an arm that a mocap body pulls along by its hand).
    Joints nothing drives (a goal marker's slides, an object's joints) move nothing with the robot.

    Returns:
        ``"joint 'NAME'"``, ``"mocap body 'NAME'"`` (``... (welded to body 'B')``),
        ``"actuator 'NAME'"`` or ``None``.
    """
    welded = _mocap_welds(model)
    driven = _driven_joints(model, robot_joints, welded)
    sites = {
        int(model.site_bodyid[int(model.actuator_trnid[actuator, 0])]): actuator
        for actuator in range(model.nu)
        if int(model.actuator_trntype[actuator]) == int(mujoco.mjtTrn.mjTRN_SITE)
    }
    while body > 0:
        if int(model.body_mocapid[body]) >= 0:
            return f"mocap body {_name(model, mujoco.mjtObj.mjOBJ_BODY, body)!r}"
        if body in welded:
            mocap = _name(model, mujoco.mjtObj.mjOBJ_BODY, welded[body])
            return f"mocap body {mocap!r} (welded to body {_name(model, mujoco.mjtObj.mjOBJ_BODY, body)!r})"
        if body in sites:
            return f"actuator {_name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, sites[body])!r}"
        first, count = int(model.body_jntadr[body]), int(model.body_jntnum[body])
        for joint in range(first, first + count):
            if joint in driven:
                return f"joint {_name(model, mujoco.mjtObj.mjOBJ_JOINT, joint)!r}"
        body = int(model.body_parentid[body])
    return None


def _mocap_welds(model: mujoco.MjModel) -> dict[int, int]:
    """Body -> the mocap body an equality weld or connect constraint ties it to."""
    welds: dict[int, int] = {}
    kinds = (int(mujoco.mjtEq.mjEQ_WELD), int(mujoco.mjtEq.mjEQ_CONNECT))
    for eq in range(model.neq):
        if int(model.eq_type[eq]) not in kinds:
            continue
        ends = [int(model.eq_obj1id[eq]), int(model.eq_obj2id[eq])]
        if hasattr(model, "eq_objtype") and int(model.eq_objtype[eq]) == int(mujoco.mjtObj.mjOBJ_SITE):
            ends = [int(model.site_bodyid[end]) for end in ends]
        for this, other in (ends, ends[::-1]):
            if int(model.body_mocapid[other]) >= 0 and int(model.body_mocapid[this]) < 0:
                welds[this] = other
    return welds


def _driven_joints(model: mujoco.MjModel, robot_joints: Sequence[int], welded: Mapping[int, int]) -> set[int]:
    """The robot joints an actuator drives (directly or through a tendon), or above a body welded to a mocap body."""
    robot = {int(joint) for joint in robot_joints}
    driven = set()
    for actuator in range(model.nu):
        kind, target = int(model.actuator_trntype[actuator]), int(model.actuator_trnid[actuator, 0])
        if kind in (int(mujoco.mjtTrn.mjTRN_JOINT), int(mujoco.mjtTrn.mjTRN_JOINTINPARENT)):
            driven.add(target)
        elif kind == int(mujoco.mjtTrn.mjTRN_TENDON):
            first, count = int(model.tendon_adr[target]), int(model.tendon_num[target])
            driven.update(
                int(model.wrap_objid[wrap])
                for wrap in range(first, first + count)
                if int(model.wrap_type[wrap]) == int(mujoco.mjtWrap.mjWRAP_JOINT)
            )
    for body in welded:
        driven.update(_joints_to_world(model, body))
    return driven & robot


def _joints_to_world(model: mujoco.MjModel, body: int) -> Iterator[int]:
    """The joints from ``body`` up its kinematic tree to the world, nearest first.

    A body's pose depends on these joints only.
    """
    while body > 0:
        first, count = int(model.body_jntadr[body]), int(model.body_jntnum[body])
        yield from range(first, first + count)
        body = int(model.body_parentid[body])


def region_follow(
    name: str,
    table: Mapping[str, Any],
    stated: bool | None,
    model: mujoco.MjModel,
    robot_joints: Sequence[int],
    *,
    object_joints: Collection[int],
) -> RegionFollow:
    """Whether the region ``table`` of set ``name`` follows the robot (``stated``: the file's ``follow``).

    Left out (``stated`` is ``None``), it follows when one of the elements it names is moved by the
    robot (:func:`robot_mover`). ``object_joints``: every joint of the objects.
    """
    anchors = []
    for kind, element, key in region_names(table, f"{name}.region"):
        index = int(mujoco.mj_name2id(model, _KINDS[kind], element))
        owners = {"body": None, "site": model.site_bodyid, "geom": model.geom_bodyid}[kind]
        body = index if owners is None else int(owners[index])
        mover = robot_mover(model, body, robot_joints)
        static = mover is None and _static(model, body)
        anchors.append(Anchor(kind, element, key, _name(model, mujoco.mjtObj.mjOBJ_BODY, body), mover, static))
    follows = stated if stated is not None else any(anchor.mover is not None for anchor in anchors)
    placed = any(
        joint in object_joints
        for anchor in anchors
        for joint in _joints_to_world(model, int(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, anchor.body)))
    )
    return RegionFollow(name, bool(follows), stated is not None, tuple(anchors), placed_by_objects=placed)


def node_frames(
    root: FrameState,
    object_pos: np.ndarray,
    object_vel: np.ndarray,
    object_quat: np.ndarray | None,
    robot_q: np.ndarray,
) -> list[FrameState]:
    """A tree's M reached states as frames with their own robot coordinates ``robot_q`` (M, n_robot).

    Their robot velocities are zero (a region is located by poses only); without ``object_quat``
    every state keeps ``root``'s object orientations.
    """
    object_pos = np.asarray(object_pos, dtype=float)
    robot_v = np.zeros_like(np.asarray(root.robot_v, dtype=float))
    return [
        FrameState(
            object_pos=object_pos[node],
            object_quat=np.asarray(root.object_quat if object_quat is None else object_quat[node], dtype=float),
            object_vel=np.asarray(object_vel[node], dtype=float),
            robot_q=np.asarray(robot_q[node], dtype=float),
            robot_v=robot_v,
        )
        for node in range(object_pos.shape[0])
    ]


def _static(model: mujoco.MjModel, body: int) -> bool:
    """Whether ``body`` is fixed to the world: no joint on it or up its kinematic tree, not a mocap body."""
    while body > 0:
        if int(model.body_jntnum[body]) > 0 or int(model.body_mocapid[body]) >= 0:
            return False
        body = int(model.body_parentid[body])
    return True


def _name(model: mujoco.MjModel, kind: mujoco.mjtObj, index: int) -> str:
    return mujoco.mj_id2name(model, kind, index) or f"#{index}"
