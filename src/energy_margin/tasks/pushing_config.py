"""Settings of the planar pushing task: :class:`PushingConfig` and the shapes of the pusher's face."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

from energy_margin.errors import Constraint, InvalidParameterError, constrained
from energy_margin.tasks.config import (
    EXTENTS,
    NON_NEGATIVE,
    NON_NEGATIVE_RANGE,
    NUMBER,
    POSITIVE,
    RANGE,
    TaskConfig,
)

__all__ = ["PUSHER_FACES", "PushingConfig"]

#: Shapes of the pusher's front face (``PushingConfig.pusher_face``).
PUSHER_FACES = ("flat", "v", "arc", "fork")


@dataclass(frozen=True)
class PushingConfig(TaskConfig):
    """Planar pushing settings (SI units).

    Attributes:
        timestep: physics time step, s. 1/120 s keeps MuJoCo's default contact time constant
            (0.02 s) above two steps, which its documentation requires for stable soft contacts, and
            halves the analysis time against 1/240 s (see docs/results/performance.md).
        object_radius: cylinder radius, m.
        object_half_height: cylinder half height, m.
        object_mass: cylinder mass, kg.
        pusher_half_extents: pusher box half extents, m (the box a non-flat face is cut into).
        pusher_mass: pusher mass, kg.
        pusher_face: shape of the pusher's front face (its +y side), built of boxes: ``"flat"``
            (one box, the paper's pusher), ``"v"`` (a concave V, its apex ``face_depth`` behind
            its ends), ``"arc"`` (a concave circular arc of sagitta ``face_depth``) or ``"fork"``
            (``tine_count`` tines ``face_depth`` long). Mass, inertia and width are the box's for
            every face.
        face_depth: depth of a non-flat face's hollow: how far the V's apex, the arc's middle or
            the root between two tines lies behind the face's ends, m (below the pusher's depth,
            ``2 pusher_half_extents[1]``; a flat face ignores it).
        tine_count: tines of a ``"fork"`` face, evenly spaced with the outer ones at the pusher's
            ends (at least 2).
        tine_width: width of one tine of a ``"fork"`` face along x, m.
        wall_y: y of the wall's face, m.
        ground_z: height of the ground surface, m (objects rest with their centre at
            ``ground_z + object_half_height``).
        friction_range: per-trajectory Coulomb coefficient range of every contact.
        spawn_x: x range of initial object centres, m.
        spawn_y_top: largest initial object y, m; the spawn band extends downwards by
            ``spawn_depth_per_object * max(n_objects, 10)`` so the density does not grow with n_o.
        spawn_depth_per_object: depth of the spawn band per object, m.
        min_separation: smallest distance between initial object centres, m.
        object_speed: initial object speeds are uniform in +-this per axis, m/s.
        pusher_gap: range of the gap between the pusher centre and the lowest object, m.
        pusher_heading: range of the initial pusher yaw, rad.
        pusher_speed_x: range of the initial pusher x velocity, m/s.
        pusher_speed_y: range of the initial pusher y velocity, m/s.
        drive_factor: range of the mean forward force as a multiple of the friction of the pusher
            plus all objects, mu g (m_pusher + n_o m_object), drawn once per trajectory.
        drive_jitter: the forward force drawn each step varies by this fraction around its mean.
        lateral_force: the sideways force drawn each step is uniform in +-this, N.
        capture_speed_threshold: below this pusher speed the capture region is a disc, m/s.
        capture_disc_radius: radius of that disc around the pusher centre, m.
        capture_half_width: half width of the swept band (radial margin of the annulus), m.
        capture_behind: arc length the region extends behind the pusher centre, m.
        capture_horizon: the region covers the sweep of the next this many seconds, s.
        max_turn_radius: largest rotation radius; straight motion uses it, m.
        success_half_width: half width of the success band around the touching line, m.
        workspace: (low, high) bounds of object x and y; states outside are rejected, m.
        max_linear_acceleration: perturbation force bound per axis divided by mass, m/s^2.
        max_angular_acceleration: perturbation torque bound divided by inertia, rad/s^2.
        max_speed: reached states with a faster object are rejected, m/s.
        ground_contact: cylinder-ground contact, ``"geometry"`` (the engine's rim contacts) or
            ``"footprint"`` (one base-centre contact with the rim's spin friction); see
            :class:`~energy_margin.world.scene.Scene`.
        lateral_contact: cylinder contacts with everything but the ground, ``"geometry"`` (the
            cylinder itself) or ``"sphere"`` (a sphere of its radius at its centre: the same
            contacts in the plane of the centres, from the engine's exact sphere pairs); see
            :class:`~energy_margin.world.scene.Scene`.

    """

    # Datasets written before these settings existed were made with the cylinders' own contacts.
    recorded_defaults: ClassVar[dict[str, Any]] = {"ground_contact": "geometry", "lateral_contact": "geometry"}
    # One base contact per cylinder and spheres for the lateral pairs (docs/results/performance.md).
    fast_contacts: ClassVar[dict[str, Any]] = {"ground_contact": "footprint", "lateral_contact": "sphere"}

    timestep: float = constrained(1.0 / 120.0, POSITIVE)
    object_radius: float = constrained(0.05, POSITIVE)
    object_half_height: float = constrained(0.015, POSITIVE)
    object_mass: float = constrained(0.2, POSITIVE)
    pusher_half_extents: tuple[float, float, float] = constrained((0.4, 0.1, 0.015), EXTENTS)
    pusher_mass: float = constrained(4.0, POSITIVE)
    pusher_face: str = constrained("flat", Constraint("choice", choices=PUSHER_FACES))
    face_depth: float = constrained(0.05, POSITIVE)
    tine_count: int = constrained(4, Constraint("int", minimum=2))
    tine_width: float = constrained(0.02, POSITIVE)
    wall_y: float = constrained(1.6, NUMBER)
    ground_z: float = constrained(-0.015, NUMBER)
    friction_range: tuple[float, float] = constrained((0.1, 0.3), NON_NEGATIVE_RANGE)
    spawn_x: tuple[float, float] = constrained((0.7, 1.3), RANGE)
    spawn_y_top: float = constrained(1.0, NUMBER)
    spawn_depth_per_object: float = constrained(0.04, POSITIVE)
    min_separation: float = constrained(0.1, POSITIVE)
    object_speed: float = constrained(0.05, NON_NEGATIVE)
    pusher_gap: tuple[float, float] = constrained((0.2, 0.3), RANGE)
    pusher_heading: tuple[float, float] = constrained((-0.05, 0.05), RANGE)
    pusher_speed_x: tuple[float, float] = constrained((-0.1, 0.1), RANGE)
    pusher_speed_y: tuple[float, float] = constrained((0.02, 0.06), RANGE)
    drive_factor: tuple[float, float] = constrained((1.1, 1.6), NON_NEGATIVE_RANGE)
    drive_jitter: float = constrained(0.2, NON_NEGATIVE)
    lateral_force: float = constrained(0.4, NON_NEGATIVE)
    capture_speed_threshold: float = constrained(0.3, POSITIVE)
    capture_disc_radius: float = constrained(0.6, POSITIVE)
    capture_half_width: float = constrained(0.4, POSITIVE)
    capture_behind: float = constrained(0.06, NON_NEGATIVE)
    capture_horizon: float = constrained(1.0, POSITIVE)
    max_turn_radius: float = constrained(1000.0, POSITIVE)
    success_half_width: float = constrained(0.1, POSITIVE)
    workspace: tuple[float, float] = constrained((-0.1, 2.1), RANGE)
    max_linear_acceleration: float = constrained(2.0, NON_NEGATIVE)
    max_angular_acceleration: float = constrained(0.667, NON_NEGATIVE)
    max_speed: float = constrained(100.0, POSITIVE)
    ground_contact: str = constrained("geometry", Constraint("choice", choices=("geometry", "footprint")))
    lateral_contact: str = constrained("geometry", Constraint("choice", choices=("geometry", "sphere")))

    def check(self) -> None:
        """Raise ``InvalidParameterError`` naming the first setting that contradicts another."""
        super().check()
        half_x, half_y, _ = self.pusher_half_extents
        if self.pusher_face != "flat" and self.face_depth >= 2.0 * half_y:
            raise InvalidParameterError(
                "face_depth",
                f"must be below the pusher's depth 2 pusher_half_extents[1] ({2.0 * half_y:g} m) "
                f"for a {self.pusher_face!r} face, got {self.face_depth!r}",
            )
        if self.pusher_face == "fork" and self.tine_count * self.tine_width >= 2.0 * half_x:
            raise InvalidParameterError(
                "tine_width",
                f"must leave gaps between the {self.tine_count} tines of the {2.0 * half_x:g} m wide "
                f"pusher (tine_count x tine_width < the width), got {self.tine_width!r}",
            )
