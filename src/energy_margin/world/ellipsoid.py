"""Minimum-volume enclosing ellipsoid (Khachiyan / Todd–Yıldırım) and uniform sampling inside it.

The paper (Section II.D) represents a group of objects by the minimum-volume ellipsoid enclosing
their centres. :func:`min_volume_ellipsoid` computes it with Khachiyan's algorithm in the
Todd–Yıldırım form (with "away" steps that lower the weight of interior points), stopping when
``max_j M_j <= (1 + tol)(d + 1)``, the rule whose ellipsoid volume is provably within a factor
``(1 + tol)^((d+1)/2)`` of the optimum. Each step is a rank-one update of the lifted moment matrix
``X``; ``M`` is refreshed with a rank-one formula and recomputed exactly (Cholesky, no explicit
inverse) every few steps and before stopping. The result is then scaled so that every input point
lies inside exactly (up to rounding), whatever the tolerance.

Degenerate inputs (n <= d, collinear points in 2-D, coplanar points in 3-D, duplicates) are fitted
in their affine hull, found from the singular values of the centred points; the missing axes
(and any axis thinner than ``min_thickness``) get the radius ``min_thickness``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from energy_margin.errors import InvalidParameterError, check_float, check_int, check_positive_float, check_positive_int

__all__ = [
    "RANK_TOLERANCE",
    "Ellipsoid",
    "min_volume_ellipsoid",
]

#: Relative singular value below which a direction of the point set counts as flat.
RANK_TOLERANCE = 1e-9
#: Steps between exact recomputations of M (the rank-one updates drift slowly).
_REFRESH = 25
#: Up to this many points the whole Gram matrix is updated (O(n²) per step, no solves).
_GRAM_POINTS = 256


@dataclass(frozen=True)
class Ellipsoid:
    """The ellipsoid ``{x : ‖diag(1/radii) · rotationᵀ (x − center)‖ ≤ 1}``.

    Attributes:
        center: centre, shape (d,).
        radii: semi-axis lengths, shape (d,), largest first, all > 0.
        rotation: orthonormal matrix (d, d) whose columns are the axes (same order as ``radii``),
            with determinant +1.
        iterations: Khachiyan steps taken to find it (0 for closed-form cases).
        converged: whether the stopping rule was met before the iteration cap.
        weights: Khachiyan's weights u (n,) of the input points (the points with u > 0 are the
            ones on the boundary), or ``None`` when the ellipsoid came from a closed form
            (n = 1, duplicates, collinear points in a 1-D hull); a warm start for nearby sets.

    """

    center: np.ndarray
    radii: np.ndarray
    rotation: np.ndarray
    iterations: int = field(default=0, compare=False)
    converged: bool = field(default=True, compare=False)
    weights: np.ndarray | None = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        center = np.asarray(self.center, dtype=float)
        radii = np.asarray(self.radii, dtype=float)
        rotation = np.asarray(self.rotation, dtype=float)
        if center.ndim != 1 or center.size < 1:
            raise InvalidParameterError("center", f"must have shape (d,), got {center.shape}")
        d = center.size
        if radii.shape != (d,):
            raise InvalidParameterError("radii", f"must have shape ({d},), got {radii.shape}")
        if rotation.shape != (d, d):
            raise InvalidParameterError("rotation", f"must have shape ({d}, {d}), got {rotation.shape}")
        if not (np.all(np.isfinite(center)) and np.all(np.isfinite(radii)) and np.all(np.isfinite(rotation))):
            raise InvalidParameterError("center", "must be finite, and so must radii and rotation")
        if np.any(radii <= 0):
            raise InvalidParameterError("radii", f"must be > 0, got {radii}")
        object.__setattr__(self, "center", center)
        object.__setattr__(self, "radii", radii)
        object.__setattr__(self, "rotation", rotation)

    def snapped(self, step: float = 1e-7) -> Ellipsoid:
        """The same ellipsoid with centre, radii and rotation rounded to multiples of ``step``.

        Anything drawn from the result is bit-identical for two fits that differ by rounding
        (a change of ~1e-12 moves a value across a multiple of 1e-7 with probability ~1e-5),
        while moving the ellipsoid by at most ``step`` / 2 (m for centre and radii, and per entry
        of the rotation).

        Args:
            step: the grid, > 0 (metres for centre and radii; the rotation's entries are unitless).
        """
        check_positive_float("step", step)
        return Ellipsoid(
            np.round(self.center / step) * step,
            np.maximum(np.round(self.radii / step) * step, step),
            np.round(self.rotation / step) * step,
            iterations=self.iterations,
            converged=self.converged,
            weights=self.weights,
        )

    @property
    def dimension(self) -> int:
        """The dimension d."""
        return int(self.center.size)

    @property
    def volume(self) -> float:
        """Volume (area in 2-D)."""
        from math import gamma, pi

        d = self.dimension
        return float(pi ** (d / 2) / gamma(d / 2 + 1) * np.prod(self.radii))

    @property
    def shape_matrix(self) -> np.ndarray:
        """S = ``rotation · diag(radii) · rotationᵀ``, symmetric positive definite, (d, d).

        Free of the sign and order ambiguities of the axes; the ellipsoid is ``{c + S y : ‖y‖ ≤ 1}``.
        """
        return (self.rotation * self.radii) @ self.rotation.T

    def normalized(self, points: np.ndarray) -> np.ndarray:
        """Coordinates ``diag(1/radii) · rotationᵀ (x − center)`` of points (..., d)."""
        points = np.asarray(points, dtype=float)
        return ((points - self.center) @ self.rotation) / self.radii

    def contains(self, points: np.ndarray, tol: float = 1e-9) -> np.ndarray:
        """Whether each point (..., d) lies inside, with relative tolerance ``tol`` on the norm."""
        check_float("tol", tol, minimum=0.0)
        points = np.asarray(points, dtype=float)
        if points.shape[-1:] != (self.dimension,):
            raise InvalidParameterError("points", f"must have shape (..., {self.dimension}), got {points.shape}")
        return np.linalg.norm(self.normalized(points), axis=-1) <= 1.0 + tol

    def sample(self, rng: np.random.Generator, count: int) -> np.ndarray:
        """``count`` points drawn independently and uniformly inside, shape (count, d).

        2-D: angle U(0, 2π), radius sqrt(U); 3-D: direction uniform on the sphere (polar angle
        arccos(1 − 2U), azimuth U(0, 2π)), radius cbrt(U); other d: a normalised Gaussian
        direction and radius U^(1/d). The unit-ball points are scaled by the radii, rotated and
        translated.
        """
        check_int("count", count, minimum=0)
        d = self.dimension
        if d == 2:
            angle = rng.uniform(0.0, 2.0 * np.pi, count)
            radius = np.sqrt(rng.random(count))
            unit = np.column_stack([np.cos(angle), np.sin(angle)]) * radius[:, None]
        elif d == 3:
            polar = np.arccos(1.0 - 2.0 * rng.random(count))
            azimuth = rng.uniform(0.0, 2.0 * np.pi, count)
            radius = np.cbrt(rng.random(count))
            sin_polar = np.sin(polar)
            unit = (
                np.column_stack([sin_polar * np.cos(azimuth), sin_polar * np.sin(azimuth), np.cos(polar)])
                * radius[:, None]
            )
        else:
            direction = rng.standard_normal((count, d))
            direction /= np.maximum(np.linalg.norm(direction, axis=1, keepdims=True), 1e-300)
            unit = direction * (rng.random(count) ** (1.0 / d))[:, None]
        return self.center + (unit * self.radii) @ self.rotation.T


def _check_points(points: np.ndarray) -> np.ndarray:
    try:
        array = np.asarray(points, dtype=float)
    except (TypeError, ValueError):
        raise InvalidParameterError("points", "must be a numeric array of shape (n, d)") from None
    if array.ndim != 2 or array.shape[0] < 1 or array.shape[1] < 1:
        raise InvalidParameterError("points", f"must have shape (n, d) with n >= 1 and d >= 1, got {array.shape}")
    if not np.all(np.isfinite(array)):
        raise InvalidParameterError("points", "must be finite (no NaN or infinity)")
    return array


def min_volume_ellipsoid(
    points: np.ndarray,
    *,
    tol: float = 1e-6,
    max_iterations: int = 10_000,
    min_thickness: float = 1e-9,
    initial_weights: np.ndarray | None = None,
) -> Ellipsoid:
    """The minimum-volume ellipsoid enclosing ``points``.

    Args:
        points: shape (n, d), n >= 1 (typically d = 2 or 3).
        tol: ε of the Todd–Yıldırım stopping rule ``max_j M_j <= (1 + ε)(d + 1)``, > 0.
        max_iterations: cap on Khachiyan steps, >= 1; on reaching it the current (still
            enclosing, slightly larger) ellipsoid is returned with ``converged=False``.
        min_thickness: smallest radius, same unit as the points, > 0: the radius given to the
            axes missing from a degenerate set (collinear, coplanar, n <= d, duplicates) and the
            floor of every other radius (e.g. the objects' radius).
        initial_weights: warm start, shape (n,), >= 0 (e.g. the ``weights`` of a nearby set's
            ellipsoid); ignored (uniform start) when its support does not span the points.

    Returns:
        The ellipsoid; every input point lies inside it up to rounding (relative 1e-9).

    Raises:
        InvalidParameterError: naming the argument that is invalid.

    """
    array = _check_points(points)
    check_positive_float("tol", tol)
    check_positive_int("max_iterations", max_iterations)
    check_positive_float("min_thickness", min_thickness)
    n, d = array.shape
    start = None
    if initial_weights is not None:
        start = np.asarray(initial_weights, dtype=float)
        if start.shape != (n,) or not np.all(np.isfinite(start)) or np.any(start < 0) or start.sum() <= 0:
            raise InvalidParameterError(
                "initial_weights", f"must be {n} finite non-negative numbers with a positive sum"
            )
        start = start / start.sum()
    mean = array.mean(axis=0)
    centred = array - mean
    scale = float(np.abs(centred).max())
    # Spreads at the level of rounding noise of the coordinates count as flat.
    noise = 64.0 * np.finfo(float).eps * max(float(np.abs(array).max()), np.finfo(float).tiny) * np.sqrt(n)
    if n == 1 or scale <= noise:
        return Ellipsoid(mean, np.full(d, float(min_thickness)), np.eye(d))
    # Affine hull from the singular values of the (scaled) centred points.
    _, singular, vt = np.linalg.svd(centred / scale, full_matrices=True)
    threshold = max(RANK_TOLERANCE * singular[0], noise / scale)
    rank = int(np.count_nonzero(singular > threshold))
    while True:
        # (d, rank): orthonormal directions of the hull; full-rank sets keep their own axes.
        basis = np.eye(d) if rank == d else vt[:rank].T
        try:
            inner = _fit_full_rank(centred @ basis, tol, max_iterations, start)
            break
        except np.linalg.LinAlgError:
            if start is not None:
                start = None  # a failed warm start: start again from uniform weights
                continue
            # Too ill-conditioned for a Cholesky factor: treat the thinnest direction as flat.
            rank -= 1
    center = mean + basis @ inner.center
    complement = vt[rank:].T
    axes = np.concatenate([basis @ inner.rotation, complement], axis=1)
    # Points lie off a numerically flat hull by at most `offsets`; the flat axes get 1000 times
    # that (or min_thickness), so the final rescaling below stays within a factor 1 + 5e-7.
    offsets = np.abs((array - center) @ complement).max(axis=0) if rank < d else np.zeros(0)
    radii = np.concatenate([inner.radii, 1e3 * offsets])
    radii = np.maximum(radii, float(min_thickness))
    reach = float(np.max(np.linalg.norm(((array - center) @ axes) / radii, axis=1)))
    if reach > 1.0 + 1e-12:  # only off-hull offsets, not rounding, need it
        radii = radii * reach
    return _finish(center, axes, radii, inner.iterations, inner.converged, inner.weights)


def _finish(
    center: np.ndarray,
    axes: np.ndarray,
    radii: np.ndarray,
    iterations: int,
    converged: bool,
    weights: np.ndarray | None,
) -> Ellipsoid:
    order = np.argsort(-radii, kind="stable")
    radii, axes = radii[order], axes[:, order]
    if np.linalg.det(axes) < 0:
        axes = axes.copy()
        axes[:, -1] = -axes[:, -1]
    return Ellipsoid(center, radii, axes, iterations=iterations, converged=converged, weights=weights)


@dataclass(frozen=True)
class _Fit:
    center: np.ndarray
    radii: np.ndarray
    rotation: np.ndarray
    iterations: int
    converged: bool
    weights: np.ndarray | None


def _fit_full_rank(points: np.ndarray, tol: float, max_iterations: int, start: np.ndarray | None) -> _Fit:
    """MVEE of points (n, r) spanning R^r (centred near the origin); radii may be any >= 0."""
    r = points.shape[1]
    if r == 1:
        low, high = float(points.min()), float(points.max())
        return _Fit(np.array([(low + high) / 2.0]), np.array([(high - low) / 2.0]), np.eye(1), 0, True, None)
    scale = float(np.abs(points).max())
    p = points / scale
    weights, iterations, converged = _khachiyan(p, tol, max_iterations, start)
    center = weights @ p
    deviations = p - center
    covariance = (deviations * weights[:, None]).T @ deviations
    covariance = 0.5 * (covariance + covariance.T)
    eigenvalues, eigenvectors = np.linalg.eigh(covariance)
    eigenvalues = np.maximum(eigenvalues, 0.0)
    # Scale the covariance ellipsoid so that the farthest point lies exactly on it (this is
    # r * covariance at the optimum); measured in the eigenbasis, consistent with `contains`.
    projected = deviations @ eigenvectors
    floor = np.finfo(float).tiny
    reach = float(np.max(np.sum(projected * projected / np.maximum(eigenvalues, floor), axis=1)))
    radii = np.sqrt(eigenvalues * reach) * scale
    return _Fit(center * scale, radii, eigenvectors, iterations, converged, weights)


def _exact_m(lifted: np.ndarray, weights: np.ndarray, full: bool) -> tuple[np.ndarray, np.ndarray | None]:
    """M_j = q_jᵀ X⁻¹ q_j with X = Q diag(u) Qᵀ, and the Gram matrix Qᵀ X⁻¹ Q when ``full``.

    Solves with the Cholesky factor of X (no explicit inverse).
    """
    moment = (lifted * weights) @ lifted.T
    factor = np.linalg.cholesky(moment)
    solved = np.linalg.solve(factor, lifted)
    if full:
        gram = solved.T @ solved
        return gram.diagonal().copy(), gram
    return np.einsum("ij,ij->j", solved, solved), None


def _khachiyan(
    points: np.ndarray, tol: float, max_iterations: int, start: np.ndarray | None
) -> tuple[np.ndarray, int, bool]:
    """Todd–Yıldırım weights u (n,) of the MVEE of full-rank points (n, r), steps, converged.

    A step u <- (1 - β) u + β e_j changes X = Q diag(u) Qᵀ by a rank-one term, so M changes by
    ``(M_i - β g_i² / (1 - β + β M_j)) / (1 - β)`` with g_i = q_iᵀ X⁻¹ q_j. For few points the
    whole Gram matrix G = Qᵀ X⁻¹ Q is kept and updated the same way (g is a row of G: no
    factorisation per step); for many points g comes from one small solve per step. M is
    recomputed exactly every few steps and before stopping.
    """
    n, r = points.shape
    lifted = np.vstack([points.T, np.ones(n)])  # Q, (r + 1, n)
    dim = r + 1.0
    keep_gram = n <= _GRAM_POINTS
    weights = np.full(n, 1.0 / n)
    if start is not None:
        try:
            m, gram = _exact_m(lifted, start, keep_gram)
            weights = start.copy()
        except np.linalg.LinAlgError:
            start = None  # the warm start's support does not span the points
    if start is None:
        m, gram = _exact_m(lifted, weights, keep_gram)
    moment = (lifted * weights) @ lifted.T
    bound = (1.0 + tol) * dim
    iterations = 0
    since_refresh = 0
    while True:
        j_max = int(m.argmax())
        m_max = m[j_max]
        if m_max <= bound:
            if since_refresh == 0:
                return weights, iterations, True
            # Confirm with an exact M before stopping.
            m, gram = _exact_m(lifted, weights, keep_gram)
            since_refresh = 0
            continue
        if iterations >= max_iterations:
            return weights, iterations, False
        m_support = np.where(weights > 0, m, np.inf)
        j_min = int(m_support.argmin())
        m_min = m_support[j_min]
        if m_max / dim - 1.0 >= 1.0 - m_min / dim:
            j, m_j = j_max, m_max
            step = (m_j - dim) / (dim * (m_j - 1.0))
        else:
            # Away step: move weight off the interior-most supported point (possibly all of it).
            j, m_j = j_min, m_min
            drop = -weights[j] / max(1.0 - weights[j], 1e-300)
            step = max((m_j - dim) / (dim * (m_j - 1.0)), drop) if m_j > 1.0 + 1e-12 else drop
            if 1.0 - step + step * m_j <= 1e-9:
                # Removing this point would make X singular: take the ordinary step instead.
                j, m_j = j_max, m_max
                step = (m_j - dim) / (dim * (m_j - 1.0))
        q = lifted[:, j]
        weights *= 1.0 - step
        weights[j] += step
        weights[weights < 0] = 0.0
        shrink = step / (1.0 - step + step * m_j)
        if gram is not None:
            g = gram[j].copy()
            gram -= shrink * np.outer(g, g)
            gram /= 1.0 - step
            m = gram.diagonal().copy()
        else:
            g = lifted.T @ np.linalg.solve(moment, q)
            moment = (1.0 - step) * moment + step * np.outer(q, q)
            m = (m - shrink * g * g) / (1.0 - step)
        iterations += 1
        since_refresh += 1
        if not np.isfinite(m_j) or not np.isfinite(step):
            raise np.linalg.LinAlgError("Khachiyan step is not finite")
        if since_refresh >= _REFRESH:
            moment = (lifted * weights) @ lifted.T
            m, gram = _exact_m(lifted, weights, keep_gram)
            since_refresh = 0
