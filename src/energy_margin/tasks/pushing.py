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
from typing import Any

import numpy as np

from energy_margin.errors import check_float
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
from energy_margin.tasks.pushing_config import PUSHER_FACES, PushingConfig
from energy_margin.tasks.pushing_regions import SweptRegion, WallBand
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
_PUSHER_RGBA = (0.2, 0.7, 0.3, 1.0)
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

    def robot_commands(
        self, drives: np.ndarray, times: np.ndarray, q: np.ndarray, v: np.ndarray
    ) -> tuple[np.ndarray, None]:
        """The nominal force of every state at once: each drive's (x, y) force; no servos."""
        del times, q, v
        forces = np.zeros((drives.shape[0], 4))
        forces[:, :2] = drives[:, :2]
        return forces, None

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
