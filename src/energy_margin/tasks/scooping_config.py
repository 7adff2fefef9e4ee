"""Settings of the scooping task: :class:`ScoopingConfig`, the gripper's dimensions, drives and script times."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from energy_margin.errors import InvalidParameterError
from energy_margin.tasks.config import TaskConfig, require_non_negative, require_positive, require_ranges

__all__ = ["ScoopingConfig"]


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
