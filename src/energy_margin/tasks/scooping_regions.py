"""The region of the scooping task: boxes lifted above the table in the gripper's footprint, not falling.

With the capture margin it is the capture region, with the success height the success region.
"""

from __future__ import annotations

import numpy as np

from energy_margin.tasks.region_types import RegionShape
from energy_margin.tasks.scooping_config import ScoopingConfig

__all__ = ["BoxesAboveTable"]


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
