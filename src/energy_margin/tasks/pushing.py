"""Planar pushing of many cylinders towards a wall (paper Section III.A.1).

Geometry follows the authors' setup: upright cylinders (radius 0.05 m, height 0.03 m, 0.2 kg) on
the ground, a 0.8 m x 0.2 m pusher of 4 kg, and a wall whose face is at y = 1.6 m. The pusher is
a dynamic body with joints x, y, z (slide) and yaw (hinge), so ``robot_q = (x, y, z, yaw)``. It is
driven by a force at its centre of mass: during a scripted roll-out a fresh random force is drawn
every step around the trajectory's mean; during analysis the mean force keeps pushing, so the
end-effector follows the manipulation while the objects are perturbed.
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from energy_margin.errors import InvalidParameterError, check_choice, check_float
from energy_margin.tasks.base import (
    DesignAlias,
    DesignParameter,
    ReferenceLayout,
    RegionShape,
    RobotState,
    Task,
    TaskConfig,
    Trajectory,
    WrenchLimits,
    require_non_negative,
    require_positive,
    require_ranges,
    sample_separated,
)
from energy_margin.tasks.state_box import StateBox
from energy_margin.world.scene import Geom, Joint, Link, RigidObject, Scene
from energy_margin.world.state import FrameState

__all__ = [
    "FRAME_MARGIN",
    "PUSHER_FACES",
    "PushingConfig",
    "PushingTask",
    "SweptRegion",
    "WallBand",
    "pusher_geoms",
]

_OBJECT_RGBA = (0.95, 0.55, 0.15, 1.0)
# A drawn swept sector is made of boxes whose chords at the outer radius are at most this long, m
# (at most _SECTOR_SEGMENTS of them).
_SECTOR_CHORD = 0.02
_SECTOR_SEGMENTS = 400
_PUSHER_RGBA = (0.2, 0.7, 0.3, 1.0)
#: Shapes of the pusher's front face (``PushingConfig.pusher_face``).
PUSHER_FACES = ("flat", "v", "arc", "fork")
# An arc face is made of this many straight segments on each side of the middle.
_ARC_SEGMENTS = 4
# Thickness of a plate of a V or arc face, m.
_MIN_PLATE = 0.01


#: How far past the workspace a recorded frame's object may lie on the ground, m
#: (:attr:`PushingTask.frame_box`). Piles squeezed against the wall eject a cylinder now and then
#: (one of 20 slid 1.4 m behind the start in the 20-cylinder ablation set of ``reproduce``): the
#: ground is unbounded and such a frame is what the engine's contacts give; a frame 10 m out is
#: farther than anything slides within a roll-out, i.e. a blow-up.
FRAME_MARGIN = 10.0


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


class SweptRegion:
    """Annular sector swept by the pusher about its instantaneous centre of rotation, or a disc.

    One region, or the regions of many frames at once: with ``pusher_xy`` (F, 2) and
    ``pusher_velocity`` (F, 3) every parameter has shape (F,), and :meth:`contains` and
    :meth:`signed_distance` measure row f of positions (F, ..., 3) against frame f's region
    (:meth:`PushingTask.capture_regions`).
    """

    def __init__(self, config: PushingConfig, pusher_xy: np.ndarray, pusher_velocity: np.ndarray) -> None:
        """Build the region.

        Args:
            config: task settings.
            pusher_xy: pusher centre (2,) or (F, 2), m.
            pusher_velocity: (vx, vy, yaw rate), shape (3,) or (F, 3), m/s and rad/s.

        """
        self.config = config
        self.pusher_xy = np.asarray(pusher_xy, dtype=float)
        velocity = np.asarray(pusher_velocity, dtype=float)
        vx, vy, yaw_rate = velocity[..., 0], velocity[..., 1], velocity[..., 2]
        speed = np.hypot(vx, vy)
        #: Whether the pusher is slower than ``capture_speed_threshold`` (the region is a disc), shape () or (F,).
        self.is_disc = speed < config.capture_speed_threshold
        if self.is_disc.ndim == 0 and self.is_disc:
            return
        # A disc frame of a batch gets the sector parameters of a unit speed, which it never uses.
        speed = np.where(self.is_disc, 1.0, speed)
        turning = yaw_rate != 0
        radius = np.where(
            turning,
            np.minimum(speed / np.where(turning, np.abs(yaw_rate), 1.0), config.max_turn_radius),
            config.max_turn_radius,
        )
        turn = np.where(yaw_rate >= 0, 1.0, -1.0)
        normal = np.stack([-vy, vx], axis=-1) / speed[..., None]  # left of the motion
        self.centre = self.pusher_xy + (turn * radius)[..., None] * normal
        self.radius = radius
        self.turn = turn
        offset = self.pusher_xy - self.centre
        self.start_angle = np.arctan2(offset[..., 1], offset[..., 0])
        # The swept arc plus the margin behind: the arc the pusher covers in the horizon, capped at
        # the full circle.
        self.arc_margin = config.capture_behind / radius
        self.arc_length = np.minimum(speed * config.capture_horizon / radius, 2.0 * np.pi)

    def _per_frame(self, value: np.ndarray, xy: np.ndarray) -> np.ndarray:
        """A parameter (), (F,) or (F, 2) shaped to broadcast against positions' xy (..., 2) or (F, ..., 2)."""
        value = np.asarray(value)
        batch = self.is_disc.ndim
        return value.reshape(value.shape[:batch] + (1,) * (xy.ndim - 1 - batch) + value.shape[batch:])

    def _sector_parts(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Distance to the centre of rotation, its band slack, the shifted angle and the span, for each point."""
        config = self.config
        relative = xy - self._per_frame(self.centre, xy)
        distance = np.linalg.norm(relative, axis=-1)
        band = config.capture_half_width - np.abs(distance - self._per_frame(self.radius, xy))
        angle = self._per_frame(self.turn, xy) * (
            np.arctan2(relative[..., 1], relative[..., 0]) - self._per_frame(self.start_angle, xy)
        )
        margin = self._per_frame(self.arc_margin, xy)
        shifted = np.mod(angle + margin, 2.0 * np.pi)
        return distance, band, shifted, self._per_frame(self.arc_length, xy) + margin

    def contains(self, positions: np.ndarray, velocities: np.ndarray | None = None) -> np.ndarray:
        """Whether each position (..., 3) lies in the region (velocities unused); shape (...)."""
        del velocities
        xy = np.asarray(positions)[..., :2]
        config = self.config
        inside_workspace = _inside_workspace(xy, config)
        in_disc = np.linalg.norm(xy - self._per_frame(self.pusher_xy, xy), axis=-1) <= config.capture_disc_radius
        if self.is_disc.ndim == 0 and self.is_disc:
            return in_disc & inside_workspace
        _, band, shifted, span = self._sector_parts(xy)
        in_sector = (shifted <= span) & (band >= 0.0)
        return np.where(self._per_frame(self.is_disc, xy), in_disc, in_sector) & inside_workspace

    def signed_distance(self, positions: np.ndarray) -> np.ndarray:
        """Signed distance (m) of each position (..., 3) to the region's boundary in the plane.

        Positive inside, negative outside, zero on the boundary: the smallest of the signed
        distances to each constraint (disc or annulus band, arc, workspace), measured along the
        arc at the point's radius for the angular constraint. Exact where one constraint is
        active; otherwise a bound with the right sign.
        """
        xy = np.asarray(positions, dtype=float)[..., :2]
        config = self.config
        workspace = _workspace_distance(xy, config)
        disc = config.capture_disc_radius - np.linalg.norm(xy - self._per_frame(self.pusher_xy, xy), axis=-1)
        if self.is_disc.ndim == 0 and self.is_disc:
            return np.minimum(disc, workspace)
        distance, band, shifted, span = self._sector_parts(xy)
        angular = np.where(
            shifted <= span, np.minimum(shifted, span - shifted), -np.minimum(shifted - span, 2.0 * np.pi - shifted)
        )
        # A span of the full circle has no angular constraint.
        sector = np.where(span >= 2.0 * np.pi, band, np.minimum(band, angular * distance))
        return np.minimum(np.where(self._per_frame(self.is_disc, xy), disc, sector), workspace)

    def shapes(self) -> tuple[RegionShape, ...]:
        """The disc, or boxes along the sector's arc, as thin slabs on the ground.

        The region ignores height, so it is drawn as its footprint under the objects. The
        workspace bound is not drawn (it lies outside every picture of the task).
        """
        if self.is_disc.ndim:
            # A defect of the caller: the package draws the region of one frame only.
            raise ValueError("only the region of one frame is drawn, not a batch of regions")
        config = self.config
        z, half_height = _slab(config)
        if self.is_disc:
            centre = (float(self.pusher_xy[0]), float(self.pusher_xy[1]), z)
            return (RegionShape("cylinder", centre, (config.capture_disc_radius, half_height, 0.0)),)
        radius, arc_margin = float(self.radius), float(self.arc_margin)
        start_angle, turn = float(self.start_angle), float(self.turn)
        span = min(float(self.arc_length) + arc_margin, 2.0 * np.pi)
        outer = radius + config.capture_half_width
        count = int(np.clip(np.ceil(span * outer / _SECTOR_CHORD), 1, _SECTOR_SEGMENTS))
        step = span / count
        # Each box covers its slice of the band out to the outer radius (chords fall inside).
        half_length = outer * np.tan(0.5 * step) if step < np.pi else outer
        # The band's inner edge stops at the centre of rotation for a tight turn.
        inner = max(0.0, radius - config.capture_half_width)
        middle, half_band = 0.5 * (inner + outer), 0.5 * (outer - inner)
        shapes = []
        for index in range(count):
            angle = start_angle + turn * (-arc_margin + (index + 0.5) * step)
            direction = np.array([np.cos(angle), np.sin(angle)])
            centre_xy = self.centre + middle * direction
            shapes.append(
                RegionShape(
                    "box",
                    (float(centre_xy[0]), float(centre_xy[1]), z),
                    (half_band, float(half_length), half_height),
                    yaw=float(angle),
                )
            )
        return tuple(shapes)


class WallBand:
    """The band along the wall where the objects must end (success region)."""

    def __init__(self, config: PushingConfig) -> None:
        touching = config.wall_y - config.object_radius
        self.low = touching - config.success_half_width
        self.high = touching + config.success_half_width
        self.config = config

    def contains(self, positions: np.ndarray, velocities: np.ndarray | None = None) -> np.ndarray:
        """Whether each position (..., 3) lies in the band (velocities unused); shape (...)."""
        del velocities
        xy = np.asarray(positions)[..., :2]
        y = xy[..., 1]
        return (y >= self.low) & (y <= self.high) & _inside_workspace(xy, self.config)

    def signed_distance(self, positions: np.ndarray) -> np.ndarray:
        """Signed distance (m) of each position (..., 3) to the band's boundary: > 0 inside, < 0 outside."""
        xy = np.asarray(positions, dtype=float)[..., :2]
        y = xy[..., 1]
        return np.minimum(np.minimum(y - self.low, self.high - y), _workspace_distance(xy, self.config))

    def shapes(self) -> tuple[RegionShape, ...]:
        """One thin slab on the ground across the workspace (the band's footprint)."""
        config = self.config
        low, high = config.workspace
        z, half_height = _slab(config)
        centre = (0.5 * (low + high), 0.5 * (self.low + self.high), z)
        half = (0.5 * (high - low), 0.5 * (self.high - self.low), half_height)
        return (RegionShape("box", centre, half),)


def _slab(config: PushingConfig) -> tuple[float, float]:
    """Centre height and half thickness of a drawn footprint: 2 mm on the ground, m."""
    return config.ground_z + 0.001, 0.001


def _workspace_distance(xy: np.ndarray, config: PushingConfig) -> np.ndarray:
    """Signed distance to the workspace square's nearest edge (> 0 inside), m."""
    low, high = config.workspace
    return np.min(np.minimum(xy - low, high - xy), axis=-1)


def _inside_workspace(xy: np.ndarray, config: PushingConfig) -> np.ndarray:
    low, high = config.workspace
    return np.all((xy >= low) & (xy <= high), axis=-1)


def _yaw_quat(yaw: float) -> tuple[float, float, float, float]:
    return (float(np.cos(0.5 * yaw)), 0.0, 0.0, float(np.sin(0.5 * yaw)))


def _face_plates(points: np.ndarray, floor: float, half_z: float) -> list[Geom]:
    """Plates whose front faces follow the polyline ``points`` (x increasing, right half), and their mirror.

    Each plate is ``_MIN_PLATE`` thick; the hollow behind the plates is closed at each end by a cap
    (a box from ``floor``, the back box's front, up to just behind the face), so no object can
    enter it from the side and nothing sticks out past the ends by more than a plate's thickness.
    """
    plates = []
    for start, end in itertools.pairwise(points):
        length = float(np.linalg.norm(end - start))
        along = (end - start) / length
        normal = np.array([-along[1], along[0]])  # towards the front (+y)
        centre = 0.5 * (start + end) - 0.5 * _MIN_PLATE * normal
        yaw = float(np.arctan2(along[1], along[0]))
        for side in (1.0, -1.0):
            plates.append(
                Geom(
                    "box",
                    (0.5 * length, 0.5 * _MIN_PLATE, half_z),
                    pos=(side * float(centre[0]), float(centre[1]), 0.0),
                    quat=_yaw_quat(side * yaw),
                    rgba=_PUSHER_RGBA,
                )
            )
    # The cap's top is the face's height at the cap's inner side, which meets the last plate's back.
    end, slope = points[-1], along[1] / along[0]
    width = min(0.9 * _MIN_PLATE / along[1], _MIN_PLATE) if along[1] > 0 else _MIN_PLATE
    top = float(end[1]) - width * slope
    if top > floor:
        for side in (1.0, -1.0):
            plates.append(
                Geom(
                    "box",
                    (0.5 * width, 0.5 * (top - floor), half_z),
                    pos=(side * (float(end[0]) - 0.5 * width), 0.5 * (top + floor), 0.0),
                    rgba=_PUSHER_RGBA,
                )
            )
    return plates


def pusher_geoms(config: PushingConfig) -> tuple[Geom, ...]:
    """The pusher's boxes in its frame: one box for a flat face; a back box and the face's plates or tines.

    The first geom is named ``"pusher"``, the face's ``"pusher_face<i>"``.
    """
    half_x, half_y, half_z = config.pusher_half_extents
    if config.pusher_face == "flat":
        return (Geom("box", config.pusher_half_extents, name="pusher", rgba=_PUSHER_RGBA),)
    depth = config.face_depth
    floor = half_y - depth  # the front of the back box: the V's apex, the arc's middle, the tines' root
    back = Geom(
        "box", (half_x, half_y - 0.5 * depth, half_z), pos=(0.0, -0.5 * depth, 0.0), name="pusher", rgba=_PUSHER_RGBA
    )
    if config.pusher_face == "v":
        parts = _face_plates(np.array([[0.0, floor], [half_x, half_y]]), floor, half_z)
    elif config.pusher_face == "arc":
        radius = (half_x**2 + depth**2) / (2.0 * depth)
        angles = np.linspace(0.0, np.arcsin(min(half_x / radius, 1.0)), _ARC_SEGMENTS + 1)
        points = np.column_stack([radius * np.sin(angles), floor + radius * (1.0 - np.cos(angles))])
        points[-1] = (half_x, half_y)
        parts = _face_plates(points, floor, half_z)
    else:
        half_tine = 0.5 * config.tine_width
        centres = np.linspace(-half_x + half_tine, half_x - half_tine, config.tine_count)
        parts = [
            Geom("box", (half_tine, 0.5 * depth, half_z), pos=(float(x), half_y - 0.5 * depth, 0.0), rgba=_PUSHER_RGBA)
            for x in centres
        ]
    named = [dataclasses.replace(part, name=f"pusher_face{index}") for index, part in enumerate(parts)]
    return (back, *named)


def _pusher_width(value: Any, current: Any) -> Any:
    return [check_float("pusher_width", value) / 2.0, current[1], current[2]]


class PushingTask(Task):
    """Push n_o cylinders into the band along a wall."""

    name = "pushing"
    config_class = PushingConfig
    config: PushingConfig
    typical_objects = 10
    region_caption = (
        "Blue: the capture region, built from the frame's pusher pose and velocity: a disc of radius "
        "capture_disc_radius around the pusher while it moves slower than capture_speed_threshold, otherwise the "
        "annular sector it sweeps in the next capture_horizon seconds (so its shape depends on the state). "
        "Purple: the success band along the wall. Both are drawn as footprints on the ground."
    )
    #: The authors' PlanePushMulti files: per object x, y, theta, vx, vy, omega; the pusher's six.
    reference_layout = ReferenceLayout("PlanePushMulti", 6, 6, drives=("nominal", "coast"))

    def __init__(self, config: PushingConfig | None = None) -> None:
        super().__init__(config if config is not None else PushingConfig(likelihood_lambda=5.0))

    def build_scene(self, n_objects: int, friction: float, drive: np.ndarray | None = None) -> Scene:
        """Ground, wall, pusher and ``n_objects`` cylinders (the drive does not change the model)."""
        del drive
        cfg = self.config
        objects = tuple(
            RigidObject(
                name=f"object{i}",
                geom=Geom("cylinder", (cfg.object_radius, cfg.object_half_height), rgba=_OBJECT_RGBA),
                mass=cfg.object_mass,
            )
            for i in range(n_objects)
        )
        half_thickness = 0.5
        wall = Geom(
            "box",
            (7.0, half_thickness, 0.1),
            pos=(1.0, cfg.wall_y + half_thickness, cfg.ground_z + 0.1),
            name="wall",
        )
        ground = Geom("plane", (5.0, 5.0), pos=(1.0, 1.0, cfg.ground_z), name="ground")
        geoms = pusher_geoms(cfg)
        pusher = Link(
            name="pusher",
            geoms=geoms,
            mass=cfg.pusher_mass,
            # A non-flat face keeps the box's mass distribution: only the contact shape changes.
            inertia_shape=None if len(geoms) == 1 else Geom("box", cfg.pusher_half_extents),
            pos=(0.0, 0.0, cfg.ground_z + cfg.pusher_half_extents[2]),
            joints=(
                Joint("pusher_x", "slide", (1.0, 0.0, 0.0)),
                Joint("pusher_y", "slide", (0.0, 1.0, 0.0)),
                Joint("pusher_z", "slide", (0.0, 0.0, 1.0)),
                Joint("pusher_yaw", "hinge", (0.0, 0.0, 1.0)),
            ),
        )
        return Scene(
            objects=objects,
            robot=pusher,
            statics=(ground, wall),
            friction=friction,
            timestep=cfg.timestep,
            object_motion="upright",
            ground_contact=cfg.ground_contact,  # type: ignore[arg-type]
            lateral_contact=cfg.lateral_contact,  # type: ignore[arg-type]
        )

    def sample_trajectory(self, rng: np.random.Generator, n_objects: int) -> Trajectory:
        """Random object layout (no overlaps), pusher start, friction and drive force."""
        cfg = self.config
        depth = cfg.spawn_depth_per_object * max(n_objects, 10)
        low = np.array([cfg.spawn_x[0], cfg.spawn_y_top - depth])
        high = np.array([cfg.spawn_x[1], cfg.spawn_y_top])
        centres = sample_separated(rng, n_objects, low, high, cfg.min_separation)
        z = cfg.ground_z + cfg.object_half_height
        object_pos = np.column_stack([centres, np.full(n_objects, z)])
        object_quat = np.tile([1.0, 0.0, 0.0, 0.0], (n_objects, 1))
        object_vel = np.zeros((n_objects, 6))
        object_vel[:, :2] = rng.uniform(-cfg.object_speed, cfg.object_speed, (n_objects, 2))
        pusher_x = float(np.mean(centres[:, 0]))
        pusher_y = float(np.min(centres[:, 1]) - rng.uniform(*cfg.pusher_gap))
        heading = float(rng.uniform(*cfg.pusher_heading))
        robot_q = np.array([pusher_x, pusher_y, 0.0, heading])
        robot_v = np.array([rng.uniform(*cfg.pusher_speed_x), rng.uniform(*cfg.pusher_speed_y), 0.0, 0.0])
        friction = float(rng.uniform(*cfg.friction_range))
        total_mass = cfg.pusher_mass + n_objects * cfg.object_mass
        forward = float(rng.uniform(*cfg.drive_factor)) * friction * 9.81 * total_mass
        initial = FrameState(object_pos, object_quat, object_vel, robot_q, robot_v)
        return Trajectory(initial=initial, friction=friction, drive=np.array([0.0, forward]))

    def robot_force(self, state: RobotState, rng: np.random.Generator | None = None) -> np.ndarray:
        """World-frame force (x, y) at the pusher centre; no vertical force or torque."""
        force = np.zeros(4)
        force[:2] = state.drive[:2]
        if rng is not None:
            cfg = self.config
            force[0] += rng.uniform(-cfg.lateral_force, cfg.lateral_force)
            force[1] *= 1.0 + rng.uniform(-cfg.drive_jitter, cfg.drive_jitter)
        return force

    def capture_region(self, root: FrameState) -> SweptRegion:
        """Swept annular sector (disc at low speed) from the pusher's pose and velocity."""
        return SweptRegion(self.config, root.robot_q[:2], root.robot_v[[0, 1, 3]])

    def capture_regions(self, roots: Sequence[FrameState]) -> SweptRegion:
        """The capture regions of many frames as one batched :class:`SweptRegion` (parameters of shape (F,))."""
        return SweptRegion(
            self.config,
            np.stack([root.robot_q[:2] for root in roots]),
            np.stack([root.robot_v[[0, 1, 3]] for root in roots]),
        )

    def capture_region_shape(self, root: FrameState) -> str:
        """``"disc"`` while the pusher is slower than ``capture_speed_threshold``, else ``"sector"``."""
        return "disc" if self.capture_region(root).is_disc else "sector"

    @classmethod
    def design_aliases(cls) -> tuple[DesignAlias, ...]:
        """``pusher_width``: the full pusher width, which sets ``pusher_half_extents[0]``."""
        return (
            DesignAlias(
                "pusher_width",
                "pusher_half_extents",
                "full pusher width along x, m (pusher_half_extents[0] = v / 2; depth and height unchanged)",
                _pusher_width,
            ),
        )

    def design_space(self) -> tuple[DesignParameter, ...]:
        """The pusher family: face shape, hollow depth, tines and width (docs/howto/design.md, "Tool families")."""
        return (
            DesignParameter("pusher_face", "shape of the pusher's front face", choices=PUSHER_FACES),
            DesignParameter(
                "face_depth", "depth of the face's hollow (V apex, arc middle, tine roots), m", low=0.02, high=0.15
            ),
            DesignParameter("tine_count", "tines of a fork face", low=2, high=8, integer=True),
            DesignParameter("pusher_width", "full pusher width along x, m", low=0.4, high=1.0),
        )

    def success_region(self) -> WallBand:
        """Band of half width ``success_half_width`` around the line where cylinders touch the wall."""
        return WallBand(self.config)

    def wrench_limits(self, scene: Scene) -> WrenchLimits:
        """Planar forces m a_max and yaw torques I_zz alpha_max on every object."""
        cfg = self.config
        limits = np.zeros((scene.n_objects, 6))
        limits[:, 0] = limits[:, 1] = scene.object_masses * cfg.max_linear_acceleration
        limits[:, 5] = scene.object_inertias[:, 2] * cfg.max_angular_acceleration
        return WrenchLimits(max_wrench=limits, max_duration=cfg.max_duration)

    def _state_box(self) -> StateBox:
        """Objects inside the workspace square (and within a metre of the ground), slower than ``max_speed``.

        The objects slide on the ground (planar joints), so the height bound only refuses a frame
        whose heights are corrupt; it rejects no reached state.
        """
        cfg = self.config
        low, high = cfg.workspace
        return StateBox(
            low=(low, low, -1.0),
            high=(high, high, 1.0),
            max_speed=cfg.max_speed,
            source="pushing's workspace and max_speed",
        )

    @property
    def frame_box(self) -> StateBox:
        """The workspace widened by :data:`FRAME_MARGIN` on every side, heights -0.5 to 1 m.

        A recorded frame may hold an object pushed past the workspace's edge (the trees then
        reject every state it reaches), not one thrown into the air.
        """
        box = self.state_box
        return StateBox(
            low=(box.low[0] - FRAME_MARGIN, box.low[1] - FRAME_MARGIN, -0.5),
            high=(box.high[0] + FRAME_MARGIN, box.high[1] + FRAME_MARGIN, 1.0),
            max_speed=box.max_speed,
            source=f"pushing's workspace widened by {FRAME_MARGIN:g} m, heights -0.5 to 1 m",
        )
