from __future__ import annotations

import numpy as np
import pytest

from energy_margin.errors import InvalidParameterError
from energy_margin.planning.density import ObjectPositions, ProjectedGridDensity


def _density(
    n_projections: int = 1, cell_size: float = 0.01, dimension: int = 3, seed: int = 0
) -> ProjectedGridDensity:
    return ProjectedGridDensity(
        dimension, np.random.default_rng(seed), n_projections=n_projections, cell_size=cell_size
    )


def _crowd_and_loner(density: ProjectedGridDensity) -> None:
    """Nodes 0..8 share one feature vector (one cell); node 9 lies 1 m away (another cell)."""
    for node in range(9):
        density.add(node, np.zeros(3))
    density.add(9, np.array([1.0, -1.0, 1.0]))


@pytest.mark.parametrize("n_projections", [1, 4])
def test_selection_is_inversely_proportional_to_occupancy(n_projections: int) -> None:
    density = _density(n_projections)
    _crowd_and_loner(density)
    draws = np.random.default_rng(42).random((20_000, 3))
    picks = np.array([density.select(u) for u in draws])
    counts = np.bincount(picks, minlength=10)
    # Two occupied cells chosen uniformly: the loner gets 1/2, each crowded node 1/18.
    assert counts[9] / len(picks) == pytest.approx(0.5, abs=0.02)
    np.testing.assert_allclose(counts[:9] / len(picks), 1 / 18, atol=0.01)


def test_selection_walks_projection_cell_and_member() -> None:
    density = _density(1)
    _crowd_and_loner(density)
    # Cells are kept in insertion order: cell 0 holds nodes 0..8, cell 1 holds node 9.
    assert density.select(np.array([0.0, 0.0, 0.0])) == 0
    assert density.select(np.array([0.0, 0.49, 0.999])) == 8
    assert density.select(np.array([0.0, 0.5, 0.0])) == 9
    assert density.select(np.array([0.999, 0.999, 0.999])) == 9


def test_nearby_features_share_a_cell_and_distant_ones_do_not() -> None:
    near = _density(1, cell_size=10.0)
    near.add(0, np.full(3, 0.5))
    near.add(1, np.full(3, 0.5 + 1e-6))
    # One cell: whatever the cell draw, the member draw decides.
    assert near.select(np.array([0.0, 0.99, 0.0])) == 0
    assert near.select(np.array([0.0, 0.99, 0.99])) == 1
    far = _density(1, cell_size=10.0)
    far.add(0, np.full(3, 0.5))
    far.add(1, np.array([30.0, -30.0, 30.0]))
    # Two cells: the cell draw decides.
    assert far.select(np.array([0.0, 0.99, 0.0])) == 1
    assert far.select(np.array([0.0, 0.0, 0.99])) == 0


def test_a_single_node_is_always_selected() -> None:
    density = _density(8)
    density.add(0, np.array([0.3, 0.2, -0.1]))
    for u in np.random.default_rng(1).random((50, 3)):
        assert density.select(u) == 0


def test_projection_directions_are_seeded_unit_columns() -> None:
    first = _density(8, dimension=6, seed=3)
    assert first.directions.shape == (8, 6, 2)
    np.testing.assert_allclose(np.linalg.norm(first.directions, axis=1), 1.0)
    np.testing.assert_array_equal(first.directions, _density(8, dimension=6, seed=3).directions)
    assert not np.array_equal(first.directions, _density(8, dimension=6, seed=4).directions)


def test_density_rejects_bad_settings() -> None:
    with pytest.raises(InvalidParameterError, match="n_projections"):
        ProjectedGridDensity(3, np.random.default_rng(0), n_projections=0)
    with pytest.raises(InvalidParameterError, match="cell_size"):
        ProjectedGridDensity(3, np.random.default_rng(0), cell_size=0.0)


def test_object_position_features() -> None:
    features = ObjectPositions()
    assert features.dimension(4) == 12
    root = np.array([[1.0, 2.0, 3.0], [0.0, 0.0, 0.0]])
    pos = np.array([[1.5, 2.0, 3.0], [0.0, -0.1, 0.2]])
    np.testing.assert_allclose(features(pos, root), [0.5, 0.0, 0.0, 0.0, -0.1, 0.2])


def test_ellipsoid_features_see_centre_and_shape() -> None:
    from energy_margin.planning.density import EllipsoidFeatures
    from energy_margin.world.ellipsoid import min_volume_ellipsoid

    rng = np.random.default_rng(0)
    root = np.column_stack([rng.uniform(0, 1, 10), rng.uniform(0, 0.3, 10), np.zeros(10)])
    planar = EllipsoidFeatures(planar=True, tol=1e-9)
    assert planar.dimension(10) == 5
    assert np.allclose(planar(root, root), 0.0)
    # A translation moves only the centre features.
    moved = planar(root + np.array([0.2, -0.1, 0.0]), root)
    assert moved[:2] == pytest.approx([0.2, -0.1], abs=1e-6)
    assert np.allclose(moved[2:], 0.0, atol=1e-6)
    # Doubling the spread about the centre doubles the shape matrix (S = R diag(radii) R^T).
    centre = min_volume_ellipsoid(root[:, :2]).center
    spread = root.copy()
    spread[:, :2] = centre + 2.0 * (root[:, :2] - centre)
    shape = min_volume_ellipsoid(root[:, :2]).shape_matrix
    expected = shape[np.triu_indices(2)] * np.array([1.0, np.sqrt(2.0), 1.0])
    assert planar(spread, root)[2:] == pytest.approx(expected, abs=1e-6)
    free = EllipsoidFeatures(planar=False)
    assert free.dimension(3) == 9
    assert free(root, root).shape == (9,)
