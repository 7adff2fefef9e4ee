"""Inverse-density node selection for the EST.

Each node is mapped to a feature vector that sees every object (by default all object centres,
relative to the root) and hashed into grid cells of several random low-dimensional projections.
Selection picks a projection uniformly, then an occupied cell uniformly, then a node of that cell
uniformly: a node's chance is inversely proportional to how crowded its cell is.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np


class Features(Protocol):
    """Maps a node's object positions to the vector the density is estimated on."""

    def dimension(self, n_objects: int) -> int:
        """Length of the feature vector for ``n_objects`` objects."""
        ...

    def __call__(self, object_pos: np.ndarray, root_pos: np.ndarray) -> np.ndarray:
        """Features of object positions (n_objects, 3) given the root's, shape (dimension,), m."""
        ...


class ObjectPositions:
    """Every object's centre relative to its position at the root, flattened (3 n_objects,)."""

    def dimension(self, n_objects: int) -> int:
        """``3 n_objects``."""
        return 3 * n_objects

    def __call__(self, object_pos: np.ndarray, root_pos: np.ndarray) -> np.ndarray:
        """Displacements from the root, m."""
        return (object_pos - root_pos).ravel()


class ProjectedGridDensity:
    """Grid hashing over random projections of node features.

    Args:
        dimension: feature length D.
        rng: generator for the projection directions (part of the analysis' seeded stream).
        n_projections: number of independent projections (hash tables).
        projection_dim: dimension of each projection.
        cell_size: grid cell width in feature units (m for positions).

    """

    def __init__(
        self,
        dimension: int,
        rng: np.random.Generator,
        *,
        n_projections: int = 8,
        projection_dim: int = 2,
        cell_size: float = 0.01,
    ) -> None:
        if n_projections < 1:
            raise ValueError(f"n_projections must be >= 1, got {n_projections}")
        if cell_size <= 0:
            raise ValueError(f"cell_size must be > 0, got {cell_size}")
        directions = rng.standard_normal((n_projections, dimension, projection_dim))
        # Unit columns: a projected coordinate has the scale of one object's displacement.
        self.directions = directions / np.linalg.norm(directions, axis=1, keepdims=True)
        self.cell_size = cell_size
        self.n_projections = n_projections
        self._cells: list[dict[tuple[int, ...], list[int]]] = [{} for _ in range(n_projections)]
        self._keys: list[list[tuple[int, ...]]] = [[] for _ in range(n_projections)]

    def add(self, node: int, features: np.ndarray) -> None:
        """Insert ``node`` with its features (D,)."""
        projected = np.floor(np.einsum("d,pdk->pk", features, self.directions) / self.cell_size)
        for table, cell in enumerate(projected.astype(np.int64).tolist()):
            key = tuple(cell)
            cells = self._cells[table]
            members = cells.get(key)
            if members is None:
                cells[key] = [node]
                self._keys[table].append(key)
            else:
                members.append(node)

    def select(self, uniforms: np.ndarray) -> int:
        """A node drawn with probability inversely proportional to its cell's occupancy.

        Args:
            uniforms: three independent uniform numbers in [0, 1) choosing the projection, the
                occupied cell and the node in it.

        """
        table = int(uniforms[0] * self.n_projections)
        keys = self._keys[table]
        members = self._cells[table][keys[int(uniforms[1] * len(keys))]]
        return members[int(uniforms[2] * len(members))]
