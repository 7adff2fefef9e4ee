"""Tree methods: how each iteration picks the node it extends (EST, Monte Carlo roll-outs, RRT).

All three share the controls, the propagation and the cost of :func:`energy_margin.planning.tree.grow`,
so at the same budget they simulate the same number of propagations with the same wrench and
duration distribution and the same cost model, and Algorithm 1 scores their cost fields unchanged.

* ``est`` (the paper): inverse-density selection over random projections of the object
  displacements (:class:`~energy_margin.planning.density.ProjectedGridDensity`).
* ``montecarlo``: independent roll-outs from the frame. A budget of N propagations makes
  ``ceil(N / L)`` roll-outs of up to L = ``rollout_length`` chained propagations each (the last
  layer is partial, so the total is exactly N); each propagation starts where its roll-out's
  previous one ended, and a roll-out whose state leaves the state box restarts from the root. The
  propagations are taken layer by layer (step 1 of every roll-out, then step 2, ...), so a batch
  holds propagations of different roll-outs and the result does not depend on the batch size.
  Every reached state enters the cost field with its cost-to-come.
* ``rrt``: the authors' AO-RRT in the projected feature space. Each iteration samples a target
  uniformly in the box ``[-extent, extent]`` of object displacements from the root (every object,
  every axis; ``extent`` = ``rrt_extent``), takes the tree node nearest to it (Euclidean, brute
  force) and extends it with ONE random control: no steering towards the target, as in the
  authors' ``numControlSamples = 1``. Nodes on the frontier of the reached set have the largest
  Voronoi cells, so the tree is pulled outwards.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from energy_margin.errors import check_choice, check_positive_float, check_positive_int
from energy_margin.planning.density import Features, ProjectedGridDensity
from energy_margin.planning.tree import Expansion

__all__ = [
    "METHODS",
    "EstExpansion",
    "MonteCarloExpansion",
    "RrtExpansion",
    "expansion_factory",
]

METHODS = ("est", "montecarlo", "rrt")


class EstExpansion:
    """Inverse-density node selection (three uniforms per iteration)."""

    uniforms = 3

    def __init__(self, density: ProjectedGridDensity) -> None:
        self.density = density

    def parent(self, iteration: int, uniforms: np.ndarray, count: int) -> int | None:
        """A node drawn with probability inversely proportional to its cell's occupancy."""
        del iteration, count
        return self.density.select(uniforms)

    def added(self, iteration: int, node: int, parent: int, features: np.ndarray) -> None:
        """Hash the new node into the projections."""
        del iteration, parent
        self.density.add(node, features)

    def rejected(self, iteration: int, parent: int) -> None:
        """Nothing to do."""
        del iteration, parent


class MonteCarloExpansion:
    """Independent roll-outs from the root, taken layer by layer (no uniforms).

    Args:
        total: propagations N (the iteration budget).
        rollout_length: propagations per roll-out L, >= 1.

    """

    uniforms = 0

    def __init__(self, total: int, rollout_length: int) -> None:
        check_positive_int("rollout_length", rollout_length)
        self.n_rollouts = max(1, -(-total // rollout_length))
        self.tips = np.zeros(self.n_rollouts, dtype=np.int64)
        # The iteration whose outcome a roll-out waits for, or -1.
        self.pending = np.full(self.n_rollouts, -1, dtype=np.int64)

    def rollout_of(self, iteration: int) -> int:
        """The roll-out iteration ``iteration`` extends."""
        return iteration % self.n_rollouts

    def parent(self, iteration: int, uniforms: np.ndarray, count: int) -> int | None:
        """The end of this roll-out so far (the root at its start or after a rejection)."""
        del uniforms, count
        rollout = self.rollout_of(iteration)
        if self.pending[rollout] >= 0:
            return None
        self.pending[rollout] = iteration
        return int(self.tips[rollout])

    def added(self, iteration: int, node: int, parent: int, features: np.ndarray) -> None:
        """The roll-out continues from ``node``."""
        del parent, features
        if iteration >= 0:
            rollout = self.rollout_of(iteration)
            self.tips[rollout] = node
            self.pending[rollout] = -1

    def rejected(self, iteration: int, parent: int) -> None:
        """The roll-out left the state box: it restarts from the root."""
        del parent
        rollout = self.rollout_of(iteration)
        self.tips[rollout] = 0
        self.pending[rollout] = -1


class RrtExpansion:
    """Nearest node to a uniform target in the feature box (``dimension`` uniforms per iteration).

    Args:
        dimension: feature length D.
        capacity: largest number of nodes.
        extent: half width of the target box, feature units (m).

    """

    def __init__(self, dimension: int, capacity: int, extent: float) -> None:
        check_positive_float("extent", extent)
        self.uniforms = dimension
        self.extent = extent
        self.points = np.empty((capacity, dimension))
        self.count = 0

    def target(self, uniforms: np.ndarray) -> np.ndarray:
        """The target point of an iteration's uniforms, shape (D,)."""
        return (2.0 * np.asarray(uniforms) - 1.0) * self.extent

    def parent(self, iteration: int, uniforms: np.ndarray, count: int) -> int | None:
        """The node nearest to the target (the lowest index among equally near ones)."""
        del iteration, count
        difference = self.points[: self.count] - self.target(uniforms)
        return int(np.argmin(np.einsum("nd,nd->n", difference, difference)))

    def added(self, iteration: int, node: int, parent: int, features: np.ndarray) -> None:
        """Store the node's features."""
        del iteration, parent
        self.points[node] = features
        self.count = max(self.count, node + 1)

    def rejected(self, iteration: int, parent: int) -> None:
        """Nothing to do."""
        del iteration, parent


def expansion_factory(
    method: str,
    *,
    n_objects: int,
    total: int,
    capacity: int,
    n_projections: int = 8,
    cell_size: float = 0.01,
    rollout_length: int = 10,
    rrt_extent: float = 0.1,
) -> Callable[[np.random.Generator, np.ndarray, Features], Expansion]:
    """The ``make_expansion`` argument of :func:`~energy_margin.planning.tree.grow` for ``method``.

    Args:
        method: ``"est"``, ``"montecarlo"`` or ``"rrt"``.
        n_objects: objects in the scene.
        total: iteration budget (Monte Carlo splits it into roll-outs).
        capacity: largest number of nodes including the root.
        n_projections: EST density projections.
        cell_size: EST density grid cell, m.
        rollout_length: Monte Carlo propagations per roll-out.
        rrt_extent: RRT target box half width, m.

    """
    check_choice("method", method, METHODS)

    def make(rng: np.random.Generator, root_pos: np.ndarray, features: Features) -> Expansion:
        del root_pos
        dimension = features.dimension(n_objects)
        if method == "est":
            return EstExpansion(ProjectedGridDensity(dimension, rng, n_projections=n_projections, cell_size=cell_size))
        if method == "montecarlo":
            return MonteCarloExpansion(total, rollout_length)
        return RrtExpansion(dimension, capacity, rrt_extent)

    return make
