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
from typing import Any

import numpy as np

from energy_margin.errors import InvalidParameterError, check_float
from energy_margin.tasks.base import (
    DesignAlias,
    DesignParameter,
    ReferenceLayout,
    RobotState,
    Task,
    Trajectory,
    WrenchLimits,
    sample_separated,
)
from energy_margin.tasks.scooping_config import ScoopingConfig
from energy_margin.tasks.scooping_regions import BoxesAboveTable
from energy_margin.tasks.scooping_script import script_targets, script_targets_at
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
        fingers = tuple(self._finger(side, sign, stiffness) for side, sign in _SIDES)
        return Scene(
            objects=boxes,
            robot=self._base(fingers),
            statics=(table,),
            friction=friction,
            timestep=cfg.timestep,
            object_motion="free",
            integrator="implicitfast",
            contact_time_constant=cfg.contact_time_constant,
        )

    def _base(self, fingers: tuple[Link, ...]) -> Link:
        """The gripper's base on its vertical slide, carrying ``fingers``."""
        cfg = self.config
        total_mass = cfg.base_mass + 2.0 * (cfg.finger_mass + cfg.tip_mass)
        return Link(
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
            children=fingers,
            gravity_compensation=True,
        )

    def _finger(self, side: str, sign: float, stiffness: float) -> Link:
        """One finger on its slide (servo ``stiffness``, N/m), carrying its blade (:meth:`_tip`)."""
        cfg = self.config
        moving_mass = cfg.finger_mass + cfg.tip_mass
        return Link(
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
            children=(self._tip(side, sign),),
            gravity_compensation=True,
        )

    def _tip(self, side: str, sign: float) -> Link:
        """One blade on its hinge at the finger's lower end, with its lips (:meth:`_lips`)."""
        cfg = self.config
        return Link(
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
        return script_targets(self.config, self.contact_height, self.closed_travel, time)

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

    def robot_commands(
        self, drives: np.ndarray, times: np.ndarray, q: np.ndarray, v: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray] | None:
        """No force and the script's servo targets for every state at once (``None`` for recorded motion)."""
        del drives, q, v
        if self.config.recorded_waypoints:
            return None
        targets = script_targets_at(self.config, self.contact_height, self.closed_travel, times)
        return np.zeros((times.shape[0], 5)), targets

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
