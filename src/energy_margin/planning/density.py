"""Inverse-density node selection for the EST.

Each node is mapped to a feature vector that sees every object (by default all object centres,
relative to the root) and hashed into grid cells of several random low-dimensional projections.
Selection picks a projection uniformly, then an occupied cell uniformly, then a node of that cell
uniformly: a node's chance is inversely proportional to how crowded its cell is.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

import numpy as np

from energy_margin.errors import check_choice, check_positive_float, check_positive_int

if TYPE_CHECKING:
    from energy_margin.world.scene import Scene

__all__ = [
    "PROJECTIONS",
    "EllipsoidFeatures",
    "Features",
    "ObjectPositions",
    "ProjectedGridDensity",
    "make_features",
]

#: Names of the density projections (``AnalyzerConfig.projection``).
PROJECTIONS = ("objects", "ellipsoid")


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


class EllipsoidFeatures:
    """The minimum-volume ellipsoid of the object centres, relative to the root's (paper II.D).

    Features: the centre's displacement (d numbers) and the change of the shape matrix
    ``S = R diag(radii) Rᵀ`` (upper triangle, off-diagonal entries times sqrt 2 so that the
    Euclidean norm is the Frobenius norm; d (d + 1) / 2 numbers), all in metres. S holds the radii
    and the orientation without the sign and order ambiguities of the axes. Planar tasks use the
    2-D ellipse of (x, y) (5 features), others the 3-D ellipsoid (9 features), whatever n_o.

    Args:
        planar: fit (x, y) only.
        tol: Khachiyan tolerance; coarse (radii within about 1 %) since the features only need
            cell-size accuracy and the fit runs once per node.
        min_thickness: radius of flat axes, m.

    """

    def __init__(self, *, planar: bool, tol: float = 1e-2, min_thickness: float = 1e-3) -> None:
        from energy_margin.world.ellipsoid import min_volume_ellipsoid

        self._fit = min_volume_ellipsoid
        self.planar = planar
        self.tol = tol
        self.min_thickness = min_thickness
        d = 2 if planar else 3
        rows, cols = np.triu_indices(d)
        self._rows, self._cols = rows, cols
        self._weights = np.where(rows == cols, 1.0, np.sqrt(2.0))
        self._root: tuple[bytes, np.ndarray, np.ndarray | None] | None = None

    def dimension(self, n_objects: int) -> int:
        """``d + d (d + 1) / 2``: 5 (planar) or 9."""
        del n_objects
        d = 2 if self.planar else 3
        return d + d * (d + 1) // 2

    def _raw(self, object_pos: np.ndarray, start: np.ndarray | None) -> tuple[np.ndarray, np.ndarray | None]:
        coords = object_pos[:, :2] if self.planar else object_pos
        ellipsoid = self._fit(coords, tol=self.tol, min_thickness=self.min_thickness, initial_weights=start)
        shape = ellipsoid.shape_matrix[self._rows, self._cols] * self._weights
        return np.concatenate([ellipsoid.center, shape]), ellipsoid.weights

    def __call__(self, object_pos: np.ndarray, root_pos: np.ndarray) -> np.ndarray:
        """Centre and shape-matrix change from the root's ellipsoid, m.

        Every fit is warm-started from the root's Khachiyan weights (nodes stay near the root, so
        the boundary points mostly stay the same).
        """
        key = root_pos.tobytes()
        if self._root is None or self._root[0] != key:
            features, weights = self._raw(root_pos, None)
            self._root = (key, features, weights)
        features = self._raw(object_pos, self._root[2])[0]
        if not (np.all(np.isfinite(features)) and np.abs(features).max() < 1e3):
            features = self._raw(object_pos, None)[0]  # a degenerate warm start: fit from scratch
        return features - self._root[1]


def make_features(projection: str, scene: Scene) -> Features:
    """The density features named ``projection`` (one of :data:`PROJECTIONS`) for ``scene``."""
    if check_choice("projection", projection, PROJECTIONS) == "objects":
        return ObjectPositions()
    size = min(obj.geom.size[0] for obj in scene.objects)
    return EllipsoidFeatures(planar=scene.object_motion == "upright", min_thickness=min(size, 0.01))


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
        check_positive_int("n_projections", n_projections)
        check_positive_float("cell_size", cell_size)
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
