"""Engine-agnostic scene description.

A :class:`Scene` is an immutable model of the world: the free rigid objects that are manipulated,
the robot's end-effector as a tree of links and joints, the static obstacles, one Coulomb friction
coefficient for every contact, gravity and the physics time step. Simulator backends build their
own model from it (MuJoCo generates MJCF in code); nothing here depends on an engine.

Conventions (SI units throughout): positions in metres, masses in kilograms, quaternions
``(w, x, y, z)``, angles in radians. An object's body frame is centred at its centre of mass.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from energy_margin.errors import (
    Constraint,
    InvalidParameterError,
    check_choice,
    check_fields,
    constrained,
    constrained_required,
)

__all__ = [
    "Geom",
    "GroundContact",
    "Integrator",
    "Joint",
    "JointKind",
    "LateralContact",
    "Link",
    "ObjectMotion",
    "RigidObject",
    "Scene",
    "ShapeKind",
]

ShapeKind = Literal["box", "cylinder", "sphere", "plane"]
JointKind = Literal["slide", "hinge"]
ObjectMotion = Literal["free", "upright"]
Integrator = Literal["Euler", "implicitfast"]
GroundContact = Literal["geometry", "footprint"]
LateralContact = Literal["geometry", "sphere"]

_SIZE_LENGTH: dict[str, int] = {"box": 3, "cylinder": 2, "sphere": 1, "plane": 2}


@dataclass(frozen=True)
class Geom:
    """A primitive collision shape.

    Attributes:
        shape: ``"box"``, ``"cylinder"`` (axis along local z), ``"sphere"`` or ``"plane"`` (normal
            along local z).
        size: box half-extents ``(hx, hy, hz)``; cylinder ``(radius, half_height)``; sphere
            ``(radius,)``; plane half-sizes ``(hx, hy)`` used for display only. Metres.
        pos: position in the parent frame, metres.
        quat: orientation in the parent frame ``(w, x, y, z)``.
        name: optional name, unique within the scene when given.
        rgba: colour for viewers.

    """

    shape: ShapeKind
    size: tuple[float, ...]
    pos: tuple[float, float, float] = (0.0, 0.0, 0.0)
    quat: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)
    name: str = ""
    rgba: tuple[float, float, float, float] = (0.6, 0.6, 0.6, 1.0)

    def __post_init__(self) -> None:
        check_choice("shape", self.shape, sorted(_SIZE_LENGTH))
        if len(self.size) != _SIZE_LENGTH[self.shape]:
            raise InvalidParameterError(
                "size", f"of a {self.shape} must have {_SIZE_LENGTH[self.shape]} values, got {self.size}"
            )
        if any(not np.isfinite(s) or s <= 0 for s in self.size):
            raise InvalidParameterError("size", f"must be finite and positive, got {self.size}")

    def volume(self) -> float:
        """Volume in cubic metres (0 for a plane)."""
        if self.shape == "box":
            return 8.0 * self.size[0] * self.size[1] * self.size[2]
        if self.shape == "cylinder":
            return float(np.pi * self.size[0] ** 2 * 2.0 * self.size[1])
        if self.shape == "sphere":
            return float(4.0 / 3.0 * np.pi * self.size[0] ** 3)
        return 0.0

    def principal_inertia(self, mass: float) -> tuple[float, float, float]:
        """Principal moments of inertia about the geom's own axes for a uniform solid, kg m^2."""
        if self.shape == "box":
            hx, hy, hz = self.size
            return (
                mass * (hy**2 + hz**2) / 3.0,
                mass * (hx**2 + hz**2) / 3.0,
                mass * (hx**2 + hy**2) / 3.0,
            )
        if self.shape == "cylinder":
            radius, half_height = self.size
            lateral = mass * (3.0 * radius**2 + (2.0 * half_height) ** 2) / 12.0
            return (lateral, lateral, 0.5 * mass * radius**2)
        if self.shape == "sphere":
            moment = 0.4 * mass * self.size[0] ** 2
            return (moment, moment, moment)
        raise InvalidParameterError("shape", "must not be 'plane' for an object with mass: a plane has no inertia")


@dataclass(frozen=True)
class Joint:
    """A one-degree-of-freedom joint of the end-effector.

    Attributes:
        name: unique joint name.
        kind: ``"slide"`` (prismatic, metres) or ``"hinge"`` (revolute, radians).
        axis: joint axis in the link frame.
        limits: ``(lower, upper)`` position limits, or ``None`` for unlimited.
        damping: viscous damping, N s/m or N m s/rad.
        stiffness: passive spring stiffness towards position 0, N/m or N m/rad.
        servo_stiffness: stiffness kp of a position servo driving the joint towards a target set
            with :meth:`~energy_margin.sim.base.Simulator.set_robot_targets`, N/m or N m/rad;
            ``None`` for an unservoed joint (driven by generalized forces only).
        servo_damping: damping kv of that servo (towards zero joint velocity), N s/m or N m s/rad.
        force_limit: largest servo force or torque magnitude, N or N m; ``None`` for unlimited.

    """

    name: str
    kind: JointKind
    axis: tuple[float, float, float]
    limits: tuple[float, float] | None = None
    damping: float = 0.0
    stiffness: float = 0.0
    servo_stiffness: float | None = None
    servo_damping: float = 0.0
    force_limit: float | None = None

    def __post_init__(self) -> None:
        if self.servo_stiffness is not None and not (np.isfinite(self.servo_stiffness) and self.servo_stiffness > 0):
            raise InvalidParameterError(
                "servo_stiffness", f"of joint {self.name!r} must be > 0, got {self.servo_stiffness}"
            )
        if not (np.isfinite(self.servo_damping) and self.servo_damping >= 0):
            raise InvalidParameterError(
                "servo_damping", f"of joint {self.name!r} must be >= 0, got {self.servo_damping}"
            )
        if self.force_limit is not None and not (np.isfinite(self.force_limit) and self.force_limit > 0):
            raise InvalidParameterError("force_limit", f"of joint {self.name!r} must be > 0, got {self.force_limit}")

    @property
    def servoed(self) -> bool:
        """Whether a position servo drives this joint."""
        return self.servo_stiffness is not None


@dataclass(frozen=True)
class Link:
    """A rigid link of the end-effector, attached to its parent (or the world) by ``joints``.

    Attributes:
        name: unique link name.
        geoms: collision shapes in the link frame.
        mass: link mass, kg (inertia computed from :attr:`inertia_geom` as a uniform solid).
        pos: link origin in the parent frame, metres.
        joints: joints between the parent and this link, in order (may be empty: welded).
        children: child links.
        gravity_compensation: whether the link's own weight is cancelled (an arm or a mechanism
            carries it; loads from contacts are not compensated).
        collides_with_statics: whether the link's geoms collide with the static geoms; ``False``
            models a part that glides along a surface without being resolved as a rigid contact.
        inertia_shape: the solid (in the link frame) whose uniform-density inertia and centre the
            link gets, when it is not the first geom (a tool built of several geoms that keeps the
            mass distribution of a simpler one); ``None``: the first geom. Not a collision shape.

    """

    name: str
    geoms: tuple[Geom, ...]
    mass: float
    pos: tuple[float, float, float] = (0.0, 0.0, 0.0)
    joints: tuple[Joint, ...] = ()
    children: tuple[Link, ...] = ()
    gravity_compensation: bool = False
    collides_with_statics: bool = True
    inertia_shape: Geom | None = None

    @property
    def inertia_geom(self) -> Geom:
        """The solid the link's inertia is computed from: :attr:`inertia_shape`, else the first geom."""
        return self.inertia_shape if self.inertia_shape is not None else self.geoms[0]

    def iter_links(self) -> list[Link]:
        """This link and its descendants, depth first (the order of the generalized coordinates)."""
        links = [self]
        for child in self.children:
            links.extend(child.iter_links())
        return links


@dataclass(frozen=True)
class RigidObject:
    """A free-floating manipulated object with its centre of mass at its body origin.

    Attributes:
        name: unique name.
        geom: its collision shape, centred at the body origin.
        mass: kg.

    """

    name: str
    geom: Geom
    mass: float

    @property
    def inertia(self) -> tuple[float, float, float]:
        """Principal moments of inertia, kg m^2 (uniform solid)."""
        return self.geom.principal_inertia(self.mass)


@dataclass(frozen=True)
class Scene:
    """An immutable world description shared by every simulator backend.

    Attributes:
        objects: the manipulated free objects.
        robot: root link of the end-effector, attached to the world by its joints; ``None`` for none.
        statics: fixed obstacles (ground, walls, tables) in the world frame.
        friction: Coulomb coefficient of every contact, as the effective coefficient between two
            bodies (backends translate it to their own combination rule).
        timestep: physics time step, seconds.
        gravity: gravitational acceleration, m/s^2.
        object_motion: ``"free"`` (six degrees of freedom) or ``"upright"`` (objects translate in
            x, y, z and rotate only about the world z axis: the planar state of a pushing task, with
            the vertical kept so the ground carries the weight and friction acts as usual).
        integrator: ``"Euler"`` (semi-implicit) or ``"implicitfast"`` (servo damping and joint
            damping integrated implicitly: stable with stiff, well-damped servos on light links).
        contact_time_constant: time constant of the soft contacts, s (at least two time steps);
            ``None`` keeps the engine's default.
        ground_contact: how upright objects touch a horizontal ground plane. ``"geometry"``: the
            engine's own contact of the object's shape with the plane (MuJoCo: up to four points
            on the rim of a cylinder's base). ``"footprint"``: one point at the centre of the base
            with the same sliding friction, and the spin resistance of rim contacts (coefficient x
            weight x base radius) as dry friction of the yaw joint, while the object's shape keeps
            every lateral contact (other objects, robot, walls). Fewer contact rows per step for
            the same planar physics; only for ``object_motion="upright"`` on a horizontal ground
            plane. Backends without it use ``"geometry"``.
        lateral_contact: how upright cylinders touch everything but the ground. ``"geometry"``:
            their own shapes (the engine's general convex pairs). ``"sphere"``: through a sphere
            of the cylinder's radius at its centre, which meets the cylinder's side in the
            horizontal plane through the centre, so a contact in that plane (another upright
            cylinder of the same height, a vertical face of the robot or a wall) has the same
            point, normal and depth, from the engine's exact sphere pairs (one row where the engine
            reports a cylinder's line contact with a face as two identical ones); the cylinder
            itself keeps only the ground (or its footprint does). Only for
            ``object_motion="upright"``; other shapes keep their own. Backends without it use
            ``"geometry"``.

    """

    objects: tuple[RigidObject, ...]
    robot: Link | None
    statics: tuple[Geom, ...]
    friction: float = constrained_required(Constraint("float", minimum=0.0))
    timestep: float = constrained(1.0 / 240.0, Constraint("float", minimum=0.0, exclusive_minimum=True))
    gravity: tuple[float, float, float] = constrained((0.0, 0.0, -9.81), Constraint("floats", length=3))
    object_motion: ObjectMotion = constrained("free", Constraint("choice", choices=("free", "upright")))
    integrator: Integrator = constrained("Euler", Constraint("choice", choices=("Euler", "implicitfast")))
    contact_time_constant: float | None = constrained(None, Constraint("float", optional=True))
    ground_contact: GroundContact = constrained("geometry", Constraint("choice", choices=("geometry", "footprint")))
    lateral_contact: LateralContact = constrained("geometry", Constraint("choice", choices=("geometry", "sphere")))
    robot_joint_names: tuple[str, ...] = field(init=False)

    def __post_init__(self) -> None:
        if not self.objects:
            raise InvalidParameterError("objects", "must hold at least one object")
        check_fields(self)
        if self.contact_time_constant is not None and not self.contact_time_constant >= 2.0 * self.timestep:
            raise InvalidParameterError(
                "contact_time_constant",
                f"must be at least two time steps ({2.0 * self.timestep} s), got {self.contact_time_constant}",
            )
        if self.ground_contact == "footprint" and self.object_motion != "upright":
            raise InvalidParameterError("ground_contact", "'footprint' needs object_motion 'upright'")
        if self.lateral_contact == "sphere" and self.object_motion != "upright":
            raise InvalidParameterError("lateral_contact", "'sphere' needs object_motion 'upright'")
        names = [joint.name for link in self.robot_links for joint in link.joints]
        object.__setattr__(self, "robot_joint_names", tuple(names))

    @property
    def n_objects(self) -> int:
        """Number of manipulated objects."""
        return len(self.objects)

    @property
    def robot_links(self) -> list[Link]:
        """End-effector links, depth first."""
        return self.robot.iter_links() if self.robot is not None else []

    @property
    def robot_joints(self) -> list[Joint]:
        """End-effector joints in the order of the generalized coordinates."""
        return [joint for link in self.robot_links for joint in link.joints]

    @property
    def n_robot_dofs(self) -> int:
        """Number of end-effector joint coordinates."""
        return len(self.robot_joint_names)

    @property
    def object_masses(self) -> np.ndarray:
        """Object masses, shape (n_objects,), kg."""
        return np.array([obj.mass for obj in self.objects])

    @property
    def object_inertias(self) -> np.ndarray:
        """Principal inertias in each body frame, shape (n_objects, 3), kg m^2."""
        return np.array([obj.inertia for obj in self.objects])
