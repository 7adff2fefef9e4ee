"""The regions of the planar pushing task: the pusher's swept capture region and the success band at the wall.

Both test the objects' centres on the ground plane inside the task's workspace square; both
measure signed distances and draw as thin footprints on the ground.
"""

from __future__ import annotations

import numpy as np

from energy_margin.tasks.pushing_config import PushingConfig
from energy_margin.tasks.region_types import RegionShape

__all__ = ["SweptRegion", "WallBand"]

# A drawn swept sector is made of boxes whose chords at the outer radius are at most this long, m
# (at most _SECTOR_SEGMENTS of them).
_SECTOR_CHORD = 0.02
_SECTOR_SEGMENTS = 400


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
            # The package draws the region of one frame only.
            raise NotImplementedError("only the region of one frame is drawn, not a batch of regions")
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
