"""Settings of the scooping task: :class:`ScoopingConfig`, the gripper's dimensions, drives and script times."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from energy_margin.errors import Constraint, InvalidParameterError, constrained
from energy_margin.tasks.config import (
    EXTENTS,
    NON_NEGATIVE,
    NON_NEGATIVE_RANGE,
    NUMBER,
    POSITIVE,
    POSITIVE_RANGE,
    RANGE,
    TaskConfig,
)

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

    duration: float = constrained(2.3, POSITIVE)
    timestep: float = constrained(0.002, POSITIVE)
    likelihood_lambda: float = constrained(10000.0, NON_NEGATIVE)
    contact_time_constant: float = constrained(0.01, POSITIVE)
    table_top: float = constrained(0.0, NUMBER)
    table_half_extents: tuple[float, float, float] = constrained((0.15, 0.15, 0.02), EXTENTS)
    box_half_edge: float = constrained(0.005, POSITIVE)
    box_mass: float = constrained(0.002, POSITIVE)
    base_half_extents: tuple[float, float, float] = constrained((0.095, 0.025, 0.01), EXTENTS)
    base_mass: float = constrained(0.4, POSITIVE)
    finger_half_extents: tuple[float, float, float] = constrained((0.003, 0.02, 0.03), EXTENTS)
    finger_mass: float = constrained(0.03, POSITIVE)
    finger_stroke: float = constrained(0.0575, POSITIVE)
    tip_length: float = constrained(0.035, POSITIVE)
    tip_half_width: float = constrained(0.02, POSITIVE)
    tip_half_thickness: float = constrained(0.0005, POSITIVE)
    tip_mass: float = constrained(0.005, POSITIVE)
    lip_height: float = constrained(0.0, NON_NEGATIVE)
    tip_limits: tuple[float, float] = constrained((0.0, 1.75), RANGE)
    scoop_angle: float = constrained(1.31, NUMBER)
    open_gap: float = constrained(0.09, NUMBER)
    closed_gap: float = constrained(0.002, NUMBER)
    approach_height: float = constrained(0.02, NUMBER)
    lift_height: float = constrained(0.08, NUMBER)
    approach_end: float = constrained(0.3, NON_NEGATIVE)
    close_end: float = constrained(1.1, NUMBER)
    lift_start: float = constrained(1.3, NUMBER)
    lift_end: float = constrained(2.0, NUMBER)
    record_start: float = constrained(0.5, NON_NEGATIVE)
    base_stiffness: float = constrained(3000.0, POSITIVE)
    tip_stiffness: float = constrained(1.0, POSITIVE)
    tip_damping: float = constrained(0.01, NON_NEGATIVE)
    finger_return_stiffness: float = constrained(20.0, NON_NEGATIVE)
    finger_force_limit: float = constrained(10.0, POSITIVE)
    stiffness_range: tuple[float, float] = constrained((100.0, 2000.0), POSITIVE_RANGE)
    friction_range: tuple[float, float] = constrained((0.1, 0.8), NON_NEGATIVE_RANGE)
    spawn_x: tuple[float, float] = constrained((-0.03, 0.03), RANGE)
    spawn_y: tuple[float, float] = constrained((-0.01, 0.01), RANGE)
    max_yaw: float = constrained(np.pi / 4, NON_NEGATIVE)
    min_separation: float = constrained(0.0145, POSITIVE)
    capture_margin: float = constrained(0.0005, NON_NEGATIVE)
    fall_speed: float = constrained(0.05, POSITIVE)
    success_height: float = constrained(0.05, NON_NEGATIVE)
    workspace_xy: float = constrained(0.15, POSITIVE)
    workspace_z: tuple[float, float] = constrained((-0.005, 0.5), RANGE)
    max_linear_acceleration: float = constrained(2.0, NON_NEGATIVE)
    max_angular_acceleration: float = constrained(3.0, NON_NEGATIVE)
    max_speed: float = constrained(5.0, POSITIVE)
    recorded_waypoints: int = constrained(0, Constraint("int", minimum=0))

    def check(self) -> None:
        """Raise ``InvalidParameterError`` naming the first setting that contradicts another."""
        super().check()
        if not self.approach_end <= self.close_end <= self.lift_start <= self.lift_end <= self.duration:
            raise InvalidParameterError(
                "approach_end",
                "and the script times after it must satisfy "
                "approach_end <= close_end <= lift_start <= lift_end <= duration",
            )
        if self.recorded_waypoints == 1:
            # One waypoint has no segment to follow (the constraint refuses fewer than 0).
            raise InvalidParameterError("recorded_waypoints", f"must be 0 or at least 2, got {self.recorded_waypoints}")
        if self.contact_time_constant < 2.0 * self.timestep:
            raise InvalidParameterError("contact_time_constant", "must be at least two time steps")
        low, high = self.tip_limits
        if not low <= self.scoop_angle <= high:
            # The servo could not reach it: the blades would rest on their joint limit instead.
            raise InvalidParameterError(
                "scoop_angle", f"must lie within tip_limits [{low}, {high}] rad, got {self.scoop_angle!r}"
            )
