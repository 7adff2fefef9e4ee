"""The ``contact`` region of scene files, and the :class:`FrameLookup` every region of a scene is built with.

A :class:`ContactRegion` holds the objects whose geoms lie within a margin of target geoms
(MuJoCo's ``mj_geomDistance``), the targets taken at the analysed frame.
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np

from energy_margin.errors import check_float

__all__ = ["ContactRegion", "FrameLookup"]


class FrameLookup(Protocol):
    """The pose of a named body, site or geom at the frame a region is built from.

    Attributes:
        model: the compiled MuJoCo model (for regions that test geometry, e.g. ``contact``).
        data: MuJoCo data holding the frame's kinematics (read-only for regions).
        object_geoms: geom ids of each object, in object order.

    """

    model: Any
    data: Any
    object_geoms: list[np.ndarray]

    def __call__(self, kind: str, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Origin (3,) m and rotation matrix (3, 3) (columns: the frame's axes in world coordinates)."""
        ...


class ContactRegion:
    """Each object's geoms within ``margin`` of target geoms, the objects at their own poses.

    The targets stay where they are at the analysed frame. Distances are MuJoCo's
    ``mj_geomDistance`` between every geom of the object and every target geom (the smallest).
    """

    uses_orientation = True

    def __init__(self, lookup: FrameLookup, targets: np.ndarray, margin: float) -> None:
        """Build it.

        Args:
            lookup: the frame's model, kinematics and object geoms.
            targets: geom ids of the other body (or the one geom), shape (k,).
            margin: largest distance that counts as contact, m (>= 0).

        """
        import mujoco

        check_float("margin", margin, minimum=0.0)
        self._mujoco = mujoco
        self.model = lookup.model
        self.data = mujoco.MjData(self.model)
        self.data.geom_xpos[:] = lookup.data.geom_xpos
        self.data.geom_xmat[:] = lookup.data.geom_xmat
        self.targets = np.asarray(targets, dtype=int)
        self.object_geoms = lookup.object_geoms
        self.margin = float(margin)
        model = self.model
        # Each object geom's pose in its body frame.
        self._local_pos = [model.geom_pos[geoms].copy() for geoms in self.object_geoms]
        self._local_mat = []
        for geoms in self.object_geoms:
            mats = np.empty((len(geoms), 9))
            for row, geom in enumerate(geoms):
                mujoco.mju_quat2Mat(mats[row], model.geom_quat[geom])
            self._local_mat.append(mats.reshape(-1, 3, 3))

    def _distances(self, positions: np.ndarray, quaternions: np.ndarray | None) -> np.ndarray:
        """Smallest geom distance of each object to the targets, shape (..., n), m."""
        positions = np.asarray(positions, dtype=float)
        shape = positions.shape[:-1]
        flat_pos = positions.reshape(-1, 3)
        if quaternions is None:
            flat_quat = np.tile([1.0, 0.0, 0.0, 0.0], (flat_pos.shape[0], 1))
        else:
            flat_quat = np.asarray(quaternions, dtype=float).reshape(-1, 4)
        n = len(self.object_geoms)
        result = np.empty(flat_pos.shape[0])
        mujoco, model, data = self._mujoco, self.model, self.data
        rotation = np.empty(9)
        limit = self.margin + 1.0
        for index in range(flat_pos.shape[0]):
            obj = index % n
            geoms = self.object_geoms[obj]
            mujoco.mju_quat2Mat(rotation, flat_quat[index] / np.linalg.norm(flat_quat[index]))
            body = rotation.reshape(3, 3)
            data.geom_xpos[geoms] = flat_pos[index] + self._local_pos[obj] @ body.T
            data.geom_xmat[geoms] = (body @ self._local_mat[obj]).reshape(-1, 9)
            result[index] = min(
                mujoco.mj_geomDistance(model, data, int(geom), int(target), limit, None)
                for geom in geoms
                for target in self.targets
            )
        return result.reshape(shape)

    def signed_distance(self, positions: np.ndarray) -> np.ndarray:
        """``margin`` minus the geom distance of each object in its model orientation, m, shape (...)."""
        return self.margin - self._distances(positions, None)

    def contains(
        self, positions: np.ndarray, velocities: np.ndarray | None = None, quaternions: np.ndarray | None = None
    ) -> np.ndarray:
        """Whether each object (..., n) touches the targets (without orientations: identity)."""
        del velocities
        return self._distances(positions, quaternions) <= self.margin
