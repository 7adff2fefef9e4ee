"""Scooping small boxes from a table with a scoop gripper (paper Section III.A.2).

The gripper is modelled in code from boxes (SI units; dimensions in :class:`ScoopingConfig`):

* a **base** that moves vertically (a slide joint along z, held by a stiff position servo: the
  robot arm);
* two **fingers** hanging from the base that close in parallel along x (slide joints; a double
  parallelogram on the real device), each driven towards its target by the variable-stiffness
  drive: a position servo whose stiffness kp is drawn per trajectory, against a return spring
  that opens the finger. A compliant drive therefore closes less than commanded;
* a flat **tip** (1 mm blade) hinged at the lower end of each finger (revolute about y; small
  servos on the real device) whose angle sets the scoop position: 0 points straight down,
  pi/2 is horizontal and pointing inwards.

``robot_q = (base z, right finger, right tip, left finger, left tip)``: the base centre height
(m), each finger's closing travel from fully open (m) and each tip's angle from straight down
(rad). All gripper links are gravity compensated (the arm and the servos carry their own
weight); the boxes' weight is not.

The blades glide along the table without a rigid table contact (``collides_with_statics`` is
off for the tips): a rigid 1 mm blade in a rigid-contact engine presents a 1 mm step to a 1 cm
box and pushes it instead of sliding under it, whereas the real thin blade is pressed flat onto
the table. The base servo holds the blade's lower leading edge at the table surface.

Script (times in :class:`ScoopingConfig`): approach (the base lowers the blades onto the table),
close (the fingers close, the blades slide under the boxes), settle, lift (the base rises), hold.
The command is a smooth function of time only; during analysis the gripper keeps following it
(re-evaluated every 5 ms of a propagation) while the boxes are perturbed. With
``recorded_waypoints`` the command is instead a recorded motion carried by each trajectory's
drive (``[finger stiffness, t_1 .. t_W, q_1 (5) .. q_W (5)]``), for frames recorded with a
timing of their own (the authors' scooping frames, :mod:`energy_margin.data.reference`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from energy_margin.errors import InvalidParameterError, check_float
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
    "BoxesAboveTable",
    "ScoopingConfig",
    "ScoopingTask",
]

_BOX_RGBA = (0.95, 0.55, 0.15, 1.0)
_GRIPPER_RGBA = (0.2, 0.7, 0.3, 1.0)
_SIDES = (("right", 1.0), ("left", -1.0))


@dataclass(frozen=True)
class ScoopingConfig(TaskConfig):
    """Scooping settings (SI units).

    Attributes:
        duration: length of a scripted roll-out, s.
        timestep: physics time step, s (see docs/reference/method.md, "Scooping task", for the choice).
        likelihood_lambda: softmax inverse temperature, 1/J (chosen by a sweep, docs/results/scooping.md).
        contact_time_constant: soft-contact time constant, s (>= 2 time steps).
        table_top: height of the table surface, m.
        table_half_extents: half extents of the table box, m.
        box_half_edge: half the edge of a box, m (1 cm boxes).
        box_mass: mass of a box, kg.
        base_half_extents: half extents of the gripper base, m.
        base_mass: mass of the base, kg.
        finger_half_extents: half extents of a finger plate (thickness, width, length), m.
        finger_mass: mass of a finger, kg.
        finger_stroke: closing travel limit of a finger, m.
        tip_length: length of a blade from its hinge to its leading edge, m.
        tip_half_width: half width of a blade (along y), m.
        tip_half_thickness: half thickness of a blade, m.
        tip_mass: mass of a blade, kg.
        lip_height: height of the rims along a blade's two long edges (y = +-tip_half_width), on
            the face that carries the boxes, m; 0: no rims (the paper's flat blades). A rim is
            1 mm thick and as long as the blade; the blade's mass and inertia do not change.
        tip_limits: joint limits of a blade, rad (0 straight down, pi/2 horizontal).
        scoop_angle: commanded blade angle, rad.
        open_gap: distance between the two leading edges with the fingers open, m.
        closed_gap: commanded distance between the leading edges when closed, m.
        approach_height: height of the leading edges above the table at the start, m.
        lift_height: how far the base rises during the lift, m.
        approach_end: end of the approach (base lowered), s.
        close_end: end of the closing motion, s.
        lift_start: start of the lift, s.
        lift_end: end of the lift, s.
        record_start: first recorded frame, s (frames are evenly spaced from it to the end).
        base_stiffness: stiffness of the base servo, N/m.
        tip_stiffness: stiffness of the blade servos, N m/rad.
        tip_damping: damping of the blade servos, N m s/rad.
        finger_return_stiffness: return spring opening each finger, N/m.
        finger_force_limit: largest closing force of a finger drive, N.
        stiffness_range: per-trajectory finger drive stiffness, log-uniform, N/m.
        friction_range: per-trajectory Coulomb coefficient of every contact.
        spawn_x: x range of the initial box centres, m.
        spawn_y: y range of the initial box centres, m.
        max_yaw: initial box yaw is uniform in +-this, rad.
        min_separation: smallest distance between initial box centres, m.
        capture_margin: a captured box is at least this high above resting on the table, m.
        fall_speed: a box sinking faster than this is falling (capture and success), m/s.
        success_height: a successful box is at least this high above resting on the table, m.
        workspace_xy: states with a box centre outside +-this in x or y are rejected, m.
        workspace_z: (low, high) box centre heights; states outside are rejected, m.
        max_linear_acceleration: perturbation force bound per axis divided by the box mass, m/s^2.
        max_angular_acceleration: perturbation torque bound per axis divided by the box inertia,
            rad/s^2.
        max_speed: reached states with a faster box are rejected, m/s.
        recorded_waypoints: 0: the servos follow the scripted motion above; W > 0: each
            trajectory's drive carries W recorded waypoints of the gripper (times, s, then the 5
            joint positions per waypoint) and the servos follow them, linearly interpolated,
            held before the first and continued at the last segment's rate after the last (an
            imported motion whose timing is not this script's).

    """

    duration: float = 2.3
    timestep: float = 0.002
    likelihood_lambda: float = 10000.0
    contact_time_constant: float = 0.01
    table_top: float = 0.0
    table_half_extents: tuple[float, float, float] = (0.15, 0.15, 0.02)
    box_half_edge: float = 0.005
    box_mass: float = 0.002
    base_half_extents: tuple[float, float, float] = (0.095, 0.025, 0.01)
    base_mass: float = 0.4
    finger_half_extents: tuple[float, float, float] = (0.003, 0.02, 0.03)
    finger_mass: float = 0.03
    finger_stroke: float = 0.0575
    tip_length: float = 0.035
    tip_half_width: float = 0.02
    tip_half_thickness: float = 0.0005
    tip_mass: float = 0.005
    lip_height: float = 0.0
    tip_limits: tuple[float, float] = (0.0, 1.75)
    scoop_angle: float = 1.31
    open_gap: float = 0.09
    closed_gap: float = 0.002
    approach_height: float = 0.02
    lift_height: float = 0.08
    approach_end: float = 0.3
    close_end: float = 1.1
    lift_start: float = 1.3
    lift_end: float = 2.0
    record_start: float = 0.5
    base_stiffness: float = 3000.0
    tip_stiffness: float = 1.0
    tip_damping: float = 0.01
    finger_return_stiffness: float = 20.0
    finger_force_limit: float = 10.0
    stiffness_range: tuple[float, float] = (100.0, 2000.0)
    friction_range: tuple[float, float] = (0.1, 0.8)
    spawn_x: tuple[float, float] = (-0.03, 0.03)
    spawn_y: tuple[float, float] = (-0.01, 0.01)
    max_yaw: float = np.pi / 4
    min_separation: float = 0.0145
    capture_margin: float = 0.0005
    fall_speed: float = 0.05
    success_height: float = 0.05
    workspace_xy: float = 0.15
    workspace_z: tuple[float, float] = (-0.005, 0.5)
    max_linear_acceleration: float = 2.0
    max_angular_acceleration: float = 3.0
    max_speed: float = 5.0
    recorded_waypoints: int = 0

    def check(self) -> None:
        """Raise ``ValueError`` naming the first setting outside its valid range."""
        super().check()
        require_positive(
            self,
            "contact_time_constant",
            "table_half_extents",
            "box_half_edge",
            "box_mass",
            "base_half_extents",
            "base_mass",
            "finger_half_extents",
            "finger_mass",
            "finger_stroke",
            "tip_length",
            "tip_half_width",
            "tip_half_thickness",
            "tip_mass",
            "base_stiffness",
            "tip_stiffness",
            "finger_force_limit",
            "stiffness_range",
            "min_separation",
            "fall_speed",
            "workspace_xy",
            "max_speed",
        )
        require_non_negative(
            self,
            "friction_range",
            "tip_damping",
            "finger_return_stiffness",
            "lip_height",
            "max_yaw",
            "capture_margin",
            "success_height",
            "max_linear_acceleration",
            "max_angular_acceleration",
            "approach_end",
            "record_start",
        )
        require_ranges(self, "tip_limits", "stiffness_range", "friction_range", "spawn_x", "spawn_y", "workspace_z")
        if not self.approach_end <= self.close_end <= self.lift_start <= self.lift_end <= self.duration:
            raise InvalidParameterError(
                "approach_end",
                "and the script times after it must satisfy "
                "approach_end <= close_end <= lift_start <= lift_end <= duration",
            )
        if self.recorded_waypoints < 0 or self.recorded_waypoints == 1:
            raise InvalidParameterError("recorded_waypoints", f"must be 0 or at least 2, got {self.recorded_waypoints}")
        if self.contact_time_constant < 2.0 * self.timestep:
            raise InvalidParameterError("contact_time_constant", "must be at least two time steps")
        low, high = self.tip_limits
        if not low <= self.scoop_angle <= high:
            # The servo could not reach it: the blades would rest on their joint limit instead.
            raise InvalidParameterError(
                "scoop_angle", f"must lie within tip_limits [{low}, {high}] rad, got {self.scoop_angle!r}"
            )


def _smoothstep(time: float, start: float, end: float) -> float:
    """0 before ``start``, 1 after ``end``, a C1 cubic in between."""
    if time <= start:
        return 0.0
    if time >= end:
        return 1.0
    u = (time - start) / (end - start)
    return u * u * (3.0 - 2.0 * u)


class BoxesAboveTable:
    """Boxes lifted above the table inside the gripper's footprint and not falling.

    A box is inside when its centre is at least ``height`` above its resting height on the table,
    within the gripper's lateral footprint (the gripper moves only vertically, so the footprint
    does not depend on the frame), and it does not sink faster than ``fall_speed``. Above the
    table nothing but the blades can carry a box, so for the capture margin this means "resting
    on the blades, not on the table, not falling".
    """

    def __init__(self, config: ScoopingConfig, height: float) -> None:
        """Build the region.

        Args:
            config: task settings.
            height: least height of a box centre above its resting height on the table, m.

        """
        self.min_z = config.table_top + config.box_half_edge + height
        # The region is open upwards; drawings stop at the height the lift reaches.
        self.drawn_top = config.table_top + config.approach_height + config.lift_height + config.success_height
        self.half_x = config.open_gap / 2.0 + config.tip_length
        self.half_y = config.tip_half_width + config.box_half_edge
        self.fall_speed = config.fall_speed

    def contains(self, positions: np.ndarray, velocities: np.ndarray | None = None) -> np.ndarray:
        """Whether each box state lies in the region; positions (..., 3), velocities (..., 6)."""
        positions = np.asarray(positions)
        inside = (
            (positions[..., 2] >= self.min_z)
            & (np.abs(positions[..., 0]) <= self.half_x)
            & (np.abs(positions[..., 1]) <= self.half_y)
        )
        if velocities is not None:
            inside &= np.asarray(velocities)[..., 2] >= -self.fall_speed
        return inside

    def signed_distance(self, positions: np.ndarray) -> np.ndarray:
        """Signed distance (m) of each box centre (..., 3) to the region's boundary: > 0 inside.

        The smallest of the distances to the height floor and the footprint's sides; velocities
        (the falling test) are not distances and are left out.
        """
        positions = np.asarray(positions, dtype=float)
        return np.minimum(
            positions[..., 2] - self.min_z,
            np.minimum(self.half_x - np.abs(positions[..., 0]), self.half_y - np.abs(positions[..., 1])),
        )

    def shapes(self) -> tuple[RegionShape, ...]:
        """One box over the footprint from ``min_z`` up to ``drawn_top`` (the region is open upwards)."""
        half_z = 0.5 * (self.drawn_top - self.min_z)
        return (RegionShape("box", (0.0, 0.0, self.min_z + half_z), (self.half_x, self.half_y, half_z)),)


def _blade_width(value: Any, current: Any) -> Any:
    del current
    return check_float("blade_width", value) / 2.0


def _single_stiffness(value: Any, current: Any) -> Any:
    del current
    return [value, value]


class ScoopingTask(Task):
    """Scoop n_o boxes (default 5) from a table and lift them."""

    name = "scooping"
    config_class = ScoopingConfig
    config: ScoopingConfig
    control_period = 0.005
    typical_objects = 5
    region_caption = (
        "Blue: the capture region (box centres above the table in the gripper's footprint, not falling), the same "
        "for every frame. Purple: the success region, success_height above the table. Both are open upwards and "
        "drawn up to the lift's height."
    )
    #: The authors' GripperMulti files: 12 columns per box, the gripper's ten; their gripper's
    #: timing is not this task's script, so analysis replays its recorded motion.
    reference_layout = ReferenceLayout("GripperMulti", 12, 10, replays_recorded=True)

    @classmethod
    def design_aliases(cls) -> tuple[DesignAlias, ...]:
        """``finger_stiffness`` (sets ``stiffness_range`` to one value) and ``blade_width`` (``tip_half_width``)."""
        return (
            DesignAlias(
                "finger_stiffness",
                "stiffness_range",
                "finger drive stiffness, N/m: every trajectory uses this one value (stiffness_range = [v, v]) "
                "instead of a log-uniform draw",
                _single_stiffness,
            ),
            DesignAlias(
                "blade_width",
                "tip_half_width",
                "full width of a blade along y, m (tip_half_width = v / 2)",
                _blade_width,
            ),
        )

    def design_space(self) -> tuple[DesignParameter, ...]:
        """The blade family: width, length, tip angle and rim height (docs/howto/design.md, "Tool families")."""
        return (
            DesignParameter("blade_width", "full width of a blade along y, m", low=0.02, high=0.06),
            DesignParameter("tip_length", "blade length from its hinge to its leading edge, m", low=0.025, high=0.05),
            DesignParameter("scoop_angle", "blade (tip) angle from straight down, rad", low=1.1, high=1.6),
            DesignParameter("lip_height", "height of the rims along the blades' long edges, m", low=0.0, high=0.006),
        )

    def __init__(self, config: ScoopingConfig | None = None) -> None:
        super().__init__(config if config is not None else ScoopingConfig())

    # Geometry -------------------------------------------------------------------------------

    @property
    def hinge_open_x(self) -> float:
        """|x| of a blade hinge with the fingers open, m."""
        cfg = self.config
        angle = cfg.scoop_angle
        return cfg.open_gap / 2.0 + cfg.tip_length * np.sin(angle) + cfg.tip_half_thickness * np.cos(angle)

    @property
    def closed_travel(self) -> float:
        """Finger travel that brings the leading edges ``closed_gap`` apart, m."""
        cfg = self.config
        return (cfg.open_gap - cfg.closed_gap) / 2.0

    @property
    def contact_height(self) -> float:
        """Base height at which the blades' lower leading edges touch the table, m."""
        cfg = self.config
        angle = cfg.scoop_angle
        return (
            cfg.table_top
            + cfg.tip_length * np.cos(angle)
            + cfg.tip_half_thickness * np.sin(angle)
            + cfg.base_half_extents[2]
            + 2.0 * cfg.finger_half_extents[2]
        )

    @property
    def rest_height(self) -> float:
        """Centre height of a box resting on the table, m."""
        return self.config.table_top + self.config.box_half_edge

    def waypoints(self, drive: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The recorded motion of a drive: times (W,) s and joint positions (W, 5).

        Raises:
            InvalidParameterError: the drive does not hold ``recorded_waypoints`` waypoints with strictly
                increasing, finite times and finite positions.
        """
        count = self.config.recorded_waypoints
        drive = np.asarray(drive, dtype=float)
        if drive.shape != (1 + 6 * count,):
            raise InvalidParameterError(
                "drive", f"must hold 1 + 6 x {count} values (stiffness, times, joint positions)"
            )
        times, positions = self._split_waypoints(drive)
        if not (np.all(np.isfinite(drive)) and np.all(np.diff(times) > 0)):
            raise InvalidParameterError(
                "drive", "must be finite and its recorded waypoint times must increase strictly"
            )
        return times, positions

    def _split_waypoints(self, drive: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Times (W,) and joint positions (W, 5) of a drive, unchecked (:meth:`waypoints` checks)."""
        count = self.config.recorded_waypoints
        return drive[1 : 1 + count], drive[1 + count :].reshape(count, 5)

    def finger_stiffness(self, drive: np.ndarray | None) -> float:
        """Finger drive stiffness of a trajectory (geometric mean of the range without one), N/m."""
        if drive is None:
            return float(np.sqrt(np.prod(self.config.stiffness_range)))
        return float(drive[0])

    # Task interface -------------------------------------------------------------------------

    def build_scene(self, n_objects: int, friction: float, drive: np.ndarray | None = None) -> Scene:
        """Table, gripper (finger stiffness from ``drive[0]``) and ``n_objects`` boxes."""
        cfg = self.config
        if cfg.recorded_waypoints and drive is not None:
            self.waypoints(drive)  # a bad recorded motion fails here, where the scene is built
        half = cfg.box_half_edge
        boxes = tuple(
            RigidObject(f"box{i}", Geom("box", (half, half, half), rgba=_BOX_RGBA), cfg.box_mass)
            for i in range(n_objects)
        )
        table = Geom(
            "box",
            cfg.table_half_extents,
            pos=(0.0, 0.0, cfg.table_top - cfg.table_half_extents[2]),
            name="table",
        )
        stiffness = self.finger_stiffness(drive)
        moving_mass = cfg.finger_mass + cfg.tip_mass
        fingers = []
        for side, sign in _SIDES:
            tip = Link(
                name=f"{side}_tip",
                geoms=(
                    Geom(
                        "box",
                        (cfg.tip_half_thickness, cfg.tip_half_width, cfg.tip_length / 2.0),
                        pos=(0.0, 0.0, -cfg.tip_length / 2.0),
                        name=f"{side}_tip",
                        rgba=_GRIPPER_RGBA,
                    ),
                    *self._lips(side, sign),
                ),
                mass=cfg.tip_mass,
                pos=(0.0, 0.0, -2.0 * cfg.finger_half_extents[2]),
                joints=(
                    Joint(
                        f"{side}_tip",
                        "hinge",
                        (0.0, sign, 0.0),
                        limits=cfg.tip_limits,
                        servo_stiffness=cfg.tip_stiffness,
                        servo_damping=cfg.tip_damping,
                    ),
                ),
                gravity_compensation=True,
                collides_with_statics=False,
            )
            finger = Link(
                name=f"{side}_finger",
                geoms=(
                    Geom(
                        "box",
                        cfg.finger_half_extents,
                        pos=(0.0, 0.0, -cfg.finger_half_extents[2]),
                        name=f"{side}_finger",
                        rgba=_GRIPPER_RGBA,
                    ),
                ),
                mass=cfg.finger_mass,
                pos=(sign * self.hinge_open_x, 0.0, -cfg.base_half_extents[2]),
                joints=(
                    Joint(
                        f"{side}_finger",
                        "slide",
                        (-sign, 0.0, 0.0),
                        limits=(0.0, cfg.finger_stroke),
                        stiffness=cfg.finger_return_stiffness,
                        servo_stiffness=stiffness,
                        # Critically damped drive on the finger and blade.
                        servo_damping=2.0 * float(np.sqrt(stiffness * moving_mass)),
                        force_limit=cfg.finger_force_limit,
                    ),
                ),
                children=(tip,),
                gravity_compensation=True,
            )
            fingers.append(finger)
        total_mass = cfg.base_mass + 2.0 * moving_mass
        base = Link(
            name="base",
            geoms=(Geom("box", cfg.base_half_extents, name="base", rgba=_GRIPPER_RGBA),),
            mass=cfg.base_mass,
            joints=(
                Joint(
                    "base_z",
                    "slide",
                    (0.0, 0.0, 1.0),
                    servo_stiffness=cfg.base_stiffness,
                    servo_damping=2.0 * float(np.sqrt(cfg.base_stiffness * total_mass)),
                ),
            ),
            children=tuple(fingers),
            gravity_compensation=True,
        )
        return Scene(
            objects=boxes,
            robot=base,
            statics=(table,),
            friction=friction,
            timestep=cfg.timestep,
            object_motion="free",
            integrator="implicitfast",
            contact_time_constant=cfg.contact_time_constant,
        )

    def _lips(self, side: str, sign: float) -> tuple[Geom, ...]:
        """The rims along a blade's long edges, in its link frame (none for ``lip_height = 0``).

        The blade lies along the link's -z from its hinge; the face that carries the boxes once the
        blade turns inwards is the link's -x side on the right blade and its +x side on the left.
        """
        cfg = self.config
        if cfg.lip_height <= 0.0:
            return ()
        rim = cfg.tip_half_thickness  # half thickness of a rim along y
        x = -sign * (cfg.tip_half_thickness + 0.5 * cfg.lip_height)
        return tuple(
            Geom(
                "box",
                (0.5 * cfg.lip_height, rim, cfg.tip_length / 2.0),
                pos=(x, edge * (cfg.tip_half_width - rim), -cfg.tip_length / 2.0),
                name=f"{side}_tip_lip{index}",
                rgba=_GRIPPER_RGBA,
            )
            for index, edge in enumerate((1.0, -1.0))
        )

    def sample_trajectory(self, rng: np.random.Generator, n_objects: int) -> Trajectory:
        """Boxes at rest on the table (random centres and yaw), friction and drive stiffness."""
        cfg = self.config
        low = np.array([cfg.spawn_x[0], cfg.spawn_y[0]])
        high = np.array([cfg.spawn_x[1], cfg.spawn_y[1]])
        centres = sample_separated(rng, n_objects, low, high, cfg.min_separation)
        yaw = rng.uniform(-cfg.max_yaw, cfg.max_yaw, n_objects)
        object_pos = np.column_stack([centres, np.full(n_objects, self.rest_height)])
        object_quat = np.column_stack([np.cos(yaw / 2.0), np.zeros(n_objects), np.zeros(n_objects), np.sin(yaw / 2.0)])
        friction = float(rng.uniform(*cfg.friction_range))
        log_low, log_high = np.log(cfg.stiffness_range)
        stiffness = float(np.exp(rng.uniform(log_low, log_high)))
        robot_q = self._targets(0.0)
        initial = FrameState(object_pos, object_quat, np.zeros((n_objects, 6)), robot_q, np.zeros(5))
        drive = np.array([stiffness])
        if cfg.recorded_waypoints:
            # The script itself, recorded at evenly spaced times.
            times = np.linspace(0.0, cfg.duration, cfg.recorded_waypoints)
            positions = np.array([self._targets(float(time)) for time in times])
            drive = np.concatenate([drive, times, positions.ravel()])
        return Trajectory(initial=initial, friction=friction, drive=drive)

    def _targets(self, time: float) -> np.ndarray:
        """Scripted joint targets at ``time`` (s), shape (5,)."""
        cfg = self.config
        start = self.contact_height + cfg.approach_height
        base = (
            start
            - cfg.approach_height * _smoothstep(time, 0.0, cfg.approach_end)
            + cfg.lift_height * _smoothstep(time, cfg.lift_start, cfg.lift_end)
        )
        finger = self.closed_travel * _smoothstep(time, cfg.approach_end, cfg.close_end)
        return np.array([base, finger, cfg.scoop_angle, finger, cfg.scoop_angle])

    def robot_force(self, state: RobotState, rng: np.random.Generator | None = None) -> np.ndarray:
        """No generalized force: the servos move the gripper (its weight is compensated)."""
        del state, rng
        return np.zeros(5)

    def robot_targets(self, state: RobotState, rng: np.random.Generator | None = None) -> np.ndarray:
        """Servo targets, the same in roll-out and analysis: the script's, or the recorded motion's."""
        del rng
        drive, time = state.drive, state.time
        if not self.config.recorded_waypoints:
            return self._targets(time)
        # Checked once where the scene was built (build_scene), not at every servo update.
        times, positions = self._split_waypoints(drive)
        if time >= times[-1]:
            rate = (positions[-1] - positions[-2]) / (times[-1] - times[-2])
            return positions[-1] + rate * (time - times[-1])
        return np.array([np.interp(time, times, positions[:, joint]) for joint in range(positions.shape[1])])

    def capture_region(self, root: FrameState) -> BoxesAboveTable:
        """Boxes on the blades: ``capture_margin`` above the table, in the footprint, not falling."""
        del root
        return BoxesAboveTable(self.config, self.config.capture_margin)

    def capture_regions(self, roots: Sequence[FrameState]) -> BoxesAboveTable:
        """The capture region of every frame: one region (it does not depend on the frame)."""
        del roots
        return BoxesAboveTable(self.config, self.config.capture_margin)

    def success_region(self) -> BoxesAboveTable:
        """Boxes ``success_height`` (5 cm) above resting on the table and not falling."""
        return BoxesAboveTable(self.config, self.config.success_height)

    def wrench_limits(self, scene: Scene) -> WrenchLimits:
        """Forces m a_max and torques I alpha_max on every axis of every box."""
        cfg = self.config
        limits = np.zeros((scene.n_objects, 6))
        limits[:, :3] = scene.object_masses[:, None] * cfg.max_linear_acceleration
        limits[:, 3:] = scene.object_inertias * cfg.max_angular_acceleration
        return WrenchLimits(max_wrench=limits, max_duration=cfg.max_duration)

    def _state_box(self) -> StateBox:
        """Boxes above the table top (not sunk through it), over the table, slower than ``max_speed``."""
        cfg = self.config
        xy, (z_low, z_high) = cfg.workspace_xy, cfg.workspace_z
        return StateBox(
            low=(-xy, -xy, cfg.table_top + z_low),
            high=(xy, xy, cfg.table_top + z_high),
            max_speed=cfg.max_speed,
            source="scooping's workspace_xy, workspace_z and max_speed",
        )

    @property
    def frame_box(self) -> StateBox:
        """The workspace widened by 1 m on every side: a box may fall off the table, not fly away."""
        box = self.state_box
        return StateBox(
            low=(box.low[0] - 1.0, box.low[1] - 1.0, box.low[2] - 1.0),
            high=(box.high[0] + 1.0, box.high[1] + 1.0, box.high[2] + 1.0),
            max_speed=box.max_speed,
            source="scooping's workspace widened by 1 m",
        )

    def frame_steps(self, n_frames: int) -> np.ndarray:
        """Frames evenly spaced from ``record_start`` (during the closing) to the end, shape (K,)."""
        first = round(self.config.record_start / self.config.timestep)
        if n_frames == 1:
            return np.array([self.n_steps])
        return np.round(np.linspace(first, self.n_steps, n_frames)).astype(int)
