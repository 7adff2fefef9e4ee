"""Settings of the planar pushing task: :class:`PushingConfig` and the shapes of the pusher's face."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

from energy_margin.errors import InvalidParameterError, check_choice
from energy_margin.tasks.config import TaskConfig, require_non_negative, require_positive, require_ranges

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

    timestep: float = 1.0 / 120.0
    object_radius: float = 0.05
    object_half_height: float = 0.015
    object_mass: float = 0.2
    pusher_half_extents: tuple[float, float, float] = (0.4, 0.1, 0.015)
    pusher_mass: float = 4.0
    pusher_face: str = "flat"
    face_depth: float = 0.05
    tine_count: int = 4
    tine_width: float = 0.02
    wall_y: float = 1.6
    ground_z: float = -0.015
    friction_range: tuple[float, float] = (0.1, 0.3)
    spawn_x: tuple[float, float] = (0.7, 1.3)
    spawn_y_top: float = 1.0
    spawn_depth_per_object: float = 0.04
    min_separation: float = 0.1
    object_speed: float = 0.05
    pusher_gap: tuple[float, float] = (0.2, 0.3)
    pusher_heading: tuple[float, float] = (-0.05, 0.05)
    pusher_speed_x: tuple[float, float] = (-0.1, 0.1)
    pusher_speed_y: tuple[float, float] = (0.02, 0.06)
    drive_factor: tuple[float, float] = (1.1, 1.6)
    drive_jitter: float = 0.2
    lateral_force: float = 0.4
    capture_speed_threshold: float = 0.3
    capture_disc_radius: float = 0.6
    capture_half_width: float = 0.4
    capture_behind: float = 0.06
    capture_horizon: float = 1.0
    max_turn_radius: float = 1000.0
    success_half_width: float = 0.1
    workspace: tuple[float, float] = (-0.1, 2.1)
    max_linear_acceleration: float = 2.0
    max_angular_acceleration: float = 0.667
    max_speed: float = 100.0
    ground_contact: str = "geometry"
    lateral_contact: str = "geometry"

    def check(self) -> None:
        """Raise ``ValueError`` naming the first setting outside its valid range."""
        super().check()
        check_choice("ground_contact", self.ground_contact, ("geometry", "footprint"))
        check_choice("lateral_contact", self.lateral_contact, ("geometry", "sphere"))
        check_choice("pusher_face", self.pusher_face, PUSHER_FACES)
        require_positive(self, "face_depth", "tine_width")
        if self.tine_count < 2:
            raise InvalidParameterError("tine_count", f"must be at least 2, got {self.tine_count}")
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
        require_positive(
            self,
            "object_radius",
            "object_half_height",
            "object_mass",
            "pusher_half_extents",
            "pusher_mass",
            "min_separation",
            "capture_speed_threshold",
            "capture_disc_radius",
            "capture_half_width",
            "capture_horizon",
            "max_turn_radius",
            "success_half_width",
            "max_speed",
            "spawn_depth_per_object",
        )
        require_non_negative(
            self,
            "friction_range",
            "object_speed",
            "drive_jitter",
            "lateral_force",
            "capture_behind",
            "max_linear_acceleration",
            "max_angular_acceleration",
            "drive_factor",
        )
        require_ranges(
            self,
            "friction_range",
            "spawn_x",
            "pusher_gap",
            "pusher_heading",
            "pusher_speed_x",
            "pusher_speed_y",
            "drive_factor",
            "workspace",
        )
