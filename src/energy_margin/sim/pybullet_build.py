"""Building a scene in PyBullet: the optional import, shapes, bodies, the robot's multibody and servos.

:class:`_BulletBodies` holds the construction steps of
:class:`~energy_margin.sim.pybullet_backend.PybulletSimulator` (see its module docstring for the
design); the helpers here convert orientations and compute Bullet's motor gains.
"""

from __future__ import annotations

import ctypes
import os
import sys
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from energy_margin.errors import EnergyMarginError
from energy_margin.world.scene import Geom, Joint, Link, Scene

__all__: list[str] = []


def _import_pybullet() -> Any:
    """Import pybullet with its build-time banner (printed by the C library) silenced."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = (os.dup(1), os.dup(2))
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    os.dup2(devnull, 2)
    try:
        import pybullet

        ctypes.CDLL(None).fflush(None)
        return pybullet
    except ImportError:  # pragma: no cover - exercised only without the optional extra
        return None
    finally:
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for fd in (*saved, devnull):
            os.close(fd)


_pb = _import_pybullet()


_IDENTITY_XYZW = (0.0, 0.0, 0.0, 1.0)
_PLANAR = (
    ("slide", (1.0, 0.0, 0.0)),
    ("slide", (0.0, 1.0, 0.0)),
    ("slide", (0.0, 0.0, 1.0)),
    ("hinge", (0.0, 0.0, 1.0)),
)
_HIDDEN_AXES = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0))


def _is_planar(joints: tuple[Joint, ...]) -> bool:
    """Whether a link moves as an upright planar body: slides x, y, z then a hinge about z."""
    return len(joints) == 4 and all(
        joint.kind == kind and tuple(float(a) for a in joint.axis) == axis
        for joint, (kind, axis) in zip(joints, _PLANAR, strict=True)
    )


def _require_pybullet() -> Any:
    if _pb is None:
        raise EnergyMarginError("the pybullet engine needs the optional extra: pip install 'energy-margin[pybullet]'")
    return _pb


def _xyzw(quat_wxyz: tuple[float, ...] | np.ndarray) -> list[float]:
    w, x, y, z = (float(v) for v in quat_wxyz)
    return [x, y, z, w]


@dataclass
class _LinkSpec:
    """One Bullet link of a multibody under construction."""

    parent: int  # Bullet parent index: 0 = base, i = link i - 1
    pos: tuple[float, float, float]
    joint_type: int
    axis: tuple[float, float, float]
    mass: float = 0.0
    shape: int = -1
    inertial_pos: tuple[float, float, float] = (0.0, 0.0, 0.0)
    inertial_quat: list[float] = field(default_factory=lambda: list(_IDENTITY_XYZW))
    inertia: tuple[float, float, float] = (0.0, 0.0, 0.0)
    joint: Joint | None = None
    link: Link | None = None


@dataclass
class _Servo:
    index: int  # position in the robot coordinates
    joint: int  # Bullet joint index
    stiffness: float
    damping: float
    spring: float
    force_limit: float
    position_gain: float
    velocity_gain: float


def _motor_gains(stiffness: float, damping: float, effective_mass: float, dt: float) -> tuple[float, float]:
    """Bullet motor gains of a servo ``f = kp (target - q) - kv qdot`` on a joint of inertia ``M``.

    Bullet's motor asks for the end-of-step velocity ``qdot + kpb (target - q) / dt - kvb qdot``;
    an implicit PD step on inertia ``M`` gives ``kpb = kp dt^2 / M`` and ``kvb = kv dt / M``
    (to first order), each capped at 1 (a dead-beat servo).
    """
    mass = max(effective_mass, 1e-12)
    return min(1.0, stiffness * dt * dt / mass), min(1.0, damping * dt / mass)


class _BulletBodies:
    """The construction steps of :class:`~energy_margin.sim.pybullet_backend.PybulletSimulator`."""

    scene: Scene
    _pb: Any
    _client: int
    _statics: list[int]
    _robot: int
    _robot_joints: list[int]
    _n_robot: int
    _specs: list[_LinkSpec]

    # ------------------------------------------------------------------ construction

    def _shape(self, geoms: tuple[Geom, ...]) -> int:
        pb, cid = self._pb, self._client
        kinds, radii, halves, lengths, normals, positions, orientations = [], [], [], [], [], [], []
        for geom in geoms:
            kind, radius, half, length, normal = pb.GEOM_BOX, 0.5, [0.5, 0.5, 0.5], 1.0, [0.0, 0.0, 1.0]
            if geom.shape == "box":
                half = list(geom.size)
            elif geom.shape == "cylinder":
                kind, radius, length = pb.GEOM_CYLINDER, geom.size[0], 2.0 * geom.size[1]
            elif geom.shape == "sphere":
                kind, radius = pb.GEOM_SPHERE, geom.size[0]
            else:
                kind = pb.GEOM_PLANE
            kinds.append(kind)
            radii.append(radius)
            halves.append(half)
            lengths.append(length)
            normals.append(normal)
            positions.append(list(geom.pos))
            orientations.append(_xyzw(geom.quat))
        if len(geoms) == 1:
            if kinds[0] == pb.GEOM_PLANE:
                return int(
                    pb.createCollisionShape(
                        kinds[0],
                        planeNormal=normals[0],
                        collisionFramePosition=positions[0],
                        collisionFrameOrientation=orientations[0],
                        physicsClientId=cid,
                    )
                )
            return int(
                pb.createCollisionShape(
                    kinds[0],
                    radius=radii[0],
                    halfExtents=halves[0],
                    height=lengths[0],
                    collisionFramePosition=positions[0],
                    collisionFrameOrientation=orientations[0],
                    physicsClientId=cid,
                )
            )
        return int(
            pb.createCollisionShapeArray(
                shapeTypes=kinds,
                radii=radii,
                halfExtents=halves,
                lengths=lengths,
                planeNormals=normals,
                collisionFramePositions=positions,
                collisionFrameOrientations=orientations,
                physicsClientId=cid,
            )
        )

    def _static_body(self, geom: Geom) -> int:
        pb = self._pb
        shape = self._shape((Geom(geom.shape, geom.size),))
        return int(
            pb.createMultiBody(
                baseMass=0.0,
                baseCollisionShapeIndex=shape,
                basePosition=list(geom.pos),
                baseOrientation=_xyzw(geom.quat),
                physicsClientId=self._client,
            )
        )

    def _link_specs(self, link: Link, parent: int, specs: list[_LinkSpec]) -> None:
        """Append the Bullet links of ``link`` and its children (depth first, like the scene)."""
        pb = self._pb
        joints: tuple[Joint | None, ...] = link.joints or (None,)
        if _is_planar(link.joints):
            # Roll and pitch stay free (hidden) so the body can rock on its contacts, see the module docstring.
            joints = (*link.joints[:3], None, None, link.joints[3])
        for number, joint in enumerate(joints):
            last = number == len(joints) - 1
            joint_type = pb.JOINT_FIXED
            axis = (0.0, 0.0, 1.0)
            if joint is not None:
                joint_type = pb.JOINT_PRISMATIC if joint.kind == "slide" else pb.JOINT_REVOLUTE
                axis = joint.axis
            elif len(joints) > 1:
                joint_type = pb.JOINT_REVOLUTE
                axis = _HIDDEN_AXES[number - 3]
            spec = _LinkSpec(
                parent=parent,
                pos=link.pos if number == 0 else (0.0, 0.0, 0.0),
                joint_type=joint_type,
                axis=axis,
                joint=joint,
            )
            if last:
                first = link.inertia_geom
                spec.mass = link.mass
                spec.shape = self._shape(link.geoms)
                spec.inertial_pos = first.pos
                spec.inertial_quat = _xyzw(first.quat)
                spec.inertia = first.principal_inertia(link.mass)
                spec.link = link
            specs.append(spec)
            parent = len(specs)  # this link, in Bullet's 1-based parent numbering
        for child in link.children:
            self._link_specs(child, parent, specs)

    def _chain_body(self, root: Link) -> tuple[int, list[_LinkSpec]]:
        pb, cid = self._pb, self._client
        specs: list[_LinkSpec] = []
        self._link_specs(root, 0, specs)
        body = pb.createMultiBody(
            baseMass=0.0,
            baseCollisionShapeIndex=-1,
            basePosition=[0.0, 0.0, 0.0],
            linkMasses=[s.mass for s in specs],
            linkCollisionShapeIndices=[s.shape for s in specs],
            linkVisualShapeIndices=[-1] * len(specs),
            linkPositions=[list(s.pos) for s in specs],
            linkOrientations=[list(_IDENTITY_XYZW)] * len(specs),
            linkInertialFramePositions=[list(s.inertial_pos) for s in specs],
            linkInertialFrameOrientations=[s.inertial_quat for s in specs],
            linkParentIndices=[s.parent for s in specs],
            linkJointTypes=[s.joint_type for s in specs],
            linkJointAxis=[list(s.axis) for s in specs],
            physicsClientId=cid,
        )
        for index, spec in enumerate(specs):
            if spec.mass > 0:
                pb.changeDynamics(body, index, localInertiaDiagonal=list(spec.inertia), physicsClientId=cid)
            if spec.joint is not None and spec.joint.limits is not None:
                low, high = spec.joint.limits
                pb.changeDynamics(body, index, jointLowerLimit=low, jointUpperLimit=high, physicsClientId=cid)
        return int(body), specs

    def _subtree_mass(self, index: int) -> float:
        mass = self._specs[index].mass
        for child, spec in enumerate(self._specs):
            if spec.parent == index + 1:
                mass += self._subtree_mass(child)
        return mass

    def _effective_inertia(self, index: int) -> float:
        """Rough joint-space inertia of a robot joint: subtree mass (slide) or the carried link's inertia about it."""
        spec = self._specs[index]
        assert spec.joint is not None
        if spec.joint.kind == "slide":
            return self._subtree_mass(index)
        total = 0.0
        for other, candidate in enumerate(self._specs):
            if other == index or self._descends(other, index):
                offset = np.asarray(candidate.inertial_pos)
                total += float(max(candidate.inertia, default=0.0)) + candidate.mass * float(offset @ offset)
        return total

    def _descends(self, index: int, ancestor: int) -> bool:
        parent = self._specs[index].parent
        while parent > 0:
            if parent - 1 == ancestor:
                return True
            parent = self._specs[parent - 1].parent
        return False

    def _configure_robot(self) -> None:
        dt = self.scene.timestep
        self._servos: list[_Servo] = []
        self._free_joints: list[int] = []  # robot coordinates driven by generalized forces
        self._stiffness = np.zeros(self._n_robot)
        self._damping = np.zeros(self._n_robot)
        for coordinate, joint_index in enumerate(self._robot_joints):
            joint = self._specs[joint_index].joint
            assert joint is not None
            self._stiffness[coordinate] = joint.stiffness
            self._damping[coordinate] = joint.damping
            if joint.servo_stiffness is None:
                self._free_joints.append(coordinate)
                continue
            kp = joint.servo_stiffness + joint.stiffness
            kv = joint.servo_damping + joint.damping
            position_gain, velocity_gain = _motor_gains(kp, kv, self._effective_inertia(joint_index), dt)
            self._servos.append(
                _Servo(
                    coordinate,
                    joint_index,
                    joint.servo_stiffness,
                    kv,
                    joint.stiffness,
                    joint.force_limit if joint.force_limit is not None else 1e6,
                    position_gain,
                    velocity_gain,
                )
            )
        self._free_bullet = [self._robot_joints[c] for c in self._free_joints]
        self._compensated = [
            (index, spec.mass)
            for index, spec in enumerate(self._specs)
            if spec.link is not None and spec.link.gravity_compensation
        ]

    def _collision_filters(self) -> None:
        pb, cid = self._pb, self._client
        for index, spec in enumerate(self._specs):
            if spec.link is not None and not spec.link.collides_with_statics:
                for static in self._statics:
                    pb.setCollisionFilterPair(self._robot, static, index, -1, 0, physicsClientId=cid)
