"""One perturbed frame: the objects redrawn inside the minimum-volume ellipsoid of their centres.

:func:`perturb_frame` is the draw of :mod:`energy_margin.robustness.perturb` for a single frame
(the protocols, coordinates, orientations and rejection of overlaps are described there).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from energy_margin.data.dataset import Dataset
from energy_margin.errors import EnergyMarginError, InvalidParameterError
from energy_margin.world.ellipsoid import Ellipsoid, min_volume_ellipsoid
from energy_margin.world.state import FrameState

__all__ = [
    "OVERLAP_DEPTH",
    "PROTOCOLS",
    "PROTOCOL_METHODS",
    "FramePerturbation",
    "is_planar",
    "object_size",
    "perturb_frame",
]

#: Where objects not yet placed wait (far from everything, one metre apart).
_PARK_DISTANCE = 100.0
#: A perturbed frame whose deepest penetration exceeds this counts as overlapping, m.
OVERLAP_DEPTH = 5e-4
#: Perturbation protocols: physically valid states (rejection of overlaps) or the authors' draw.
PROTOCOLS = ("valid", "paper")
#: What each protocol does, as recorded in ``dataset.json``.
PROTOCOL_METHODS = {
    "valid": "uniform in the minimum-volume ellipsoid of the object centres, rejection of overlaps",
    "paper": "uniform in the minimum-volume ellipsoid of the object centres, all objects at once, overlaps allowed",
}


@dataclass(frozen=True)
class FramePerturbation:
    """Result of perturbing one frame.

    Attributes:
        frame: the perturbed state.
        ellipsoid: the ellipsoid fitted to the true centres (2-D or 3-D).
        candidates: candidates drawn (accepted and rejected).
        restarts: times the frame started over.
        growth: factor applied to the sampling ellipsoid's radii (1.0 unless the fallback ran).
        penetration: deepest contact penetration of an object in the perturbed state, m (at most
            the tolerance for the valid protocol; whatever the draw gave for the paper's).

    """

    frame: FrameState
    ellipsoid: Ellipsoid
    candidates: int
    restarts: int
    growth: float
    penetration: float = 0.0


def is_planar(dataset: Dataset) -> bool:
    """Whether the dataset's objects stay upright on a plane (their centres are redrawn in x, y only)."""
    return dataset.task.build_scene(dataset.n_objects, 0.5).object_motion == "upright"


def object_size(dataset: Dataset) -> float:
    """The smallest object's first size parameter (cylinder radius, box half edge), m."""
    scene = dataset.task.build_scene(dataset.n_objects, 0.5)
    return float(min(obj.geom.size[0] for obj in scene.objects))


def perturb_frame(
    frame: FrameState,
    simulator: Any,
    rng: np.random.Generator,
    *,
    planar: bool,
    min_thickness: float,
    tolerance: float = 5e-4,
    keep_orientation: bool = False,
    protocol: str = "valid",
    max_attempts: int = 500,
    max_restarts: int = 3,
    max_growth_restarts: int = 20,
) -> FramePerturbation:
    """Resample the object centres of ``frame`` uniformly inside their ellipsoid.

    With ``protocol="valid"`` no object overlaps anything; with ``"paper"`` (the authors' draw) the
    ``n`` centres are the first ``n`` points of the frame's stream, overlaps and all.

    Args:
        frame: the true state.
        simulator: a simulator of the frame's scene.
        rng: the frame's generator.
        planar: fit the 2-D ellipse of (x, y) and keep heights (upright objects), else 3-D.
        min_thickness: radius of the ellipsoid's flat axes (e.g. the object radius), m.
        tolerance: largest accepted contact penetration of a placed object, m.
        keep_orientation: keep the recorded orientations instead of the identity.
        protocol: ``"valid"`` (rejection of overlaps) or ``"paper"`` (the authors' draw; the
            options below and ``tolerance`` are then unused).
        max_attempts: rejected candidates of one object before the frame starts over.
        max_restarts: restarts with the fitted ellipsoid before its radii start to grow.
        max_growth_restarts: further restarts, the n-th with radii 1.1^n times larger.

    Raises:
        InvalidParameterError: when ``protocol`` is not one of :data:`PROTOCOLS`.
        EnergyMarginError: when no admissible placement is found.

    """
    if protocol not in PROTOCOLS:
        raise InvalidParameterError("protocol", f"must be one of {', '.join(PROTOCOLS)}, got {protocol!r}")
    n = frame.n_objects
    coords = frame.object_pos[:, :2] if planar else frame.object_pos
    ellipsoid = min_volume_ellipsoid(coords, min_thickness=min_thickness)
    quat = frame.object_quat.copy() if keep_orientation else np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    parked = np.column_stack(
        [np.full(n, _PARK_DISTANCE), _PARK_DISTANCE + np.arange(n, dtype=float), np.full(n, _PARK_DISTANCE)]
    )
    heights = frame.object_pos[:, 2].copy()
    if planar:
        heights[:] = _resting_height(frame, simulator, parked, quat)
    # Draws come from a snapped copy of the fit: a rounding-level change of the fit (another
    # BLAS, another Khachiyan step order) leaves every candidate, hence every decision, unchanged.
    snapped = ellipsoid.snapped()
    if protocol == "paper":
        return _paper_draw(frame, simulator, rng, ellipsoid, snapped, heights, quat, planar=planar)
    return _rejection_draw(
        frame,
        simulator,
        rng,
        ellipsoid,
        snapped,
        parked,
        heights,
        quat,
        planar=planar,
        tolerance=tolerance,
        limits=(max_attempts, max_restarts, max_growth_restarts),
    )


def _paper_draw(
    frame: FrameState,
    simulator: Any,
    rng: np.random.Generator,
    ellipsoid: Ellipsoid,
    snapped: Ellipsoid,
    heights: np.ndarray,
    quat: np.ndarray,
    *,
    planar: bool,
) -> FramePerturbation:
    """The authors' draw: every centre at once (angles, then radii), nothing checked."""
    n = frame.n_objects
    points = snapped.sample(rng, n)
    perturbed = _with_objects(frame, np.column_stack([points, heights]) if planar else points, quat)
    simulator.reset(perturbed)
    depth = _max_penetration(simulator, list(range(n)))
    return FramePerturbation(perturbed, ellipsoid, n, 0, 1.0, depth)


def _rejection_draw(
    frame: FrameState,
    simulator: Any,
    rng: np.random.Generator,
    ellipsoid: Ellipsoid,
    snapped: Ellipsoid,
    parked: np.ndarray,
    heights: np.ndarray,
    quat: np.ndarray,
    *,
    planar: bool,
    tolerance: float,
    limits: tuple[int, int, int],
) -> FramePerturbation:
    """Place the objects one by one, rejecting overlaps; start over (then with larger radii) when stuck.

    Args:
        frame: the true state.
        simulator: a simulator of the frame's scene.
        rng: the frame's generator.
        ellipsoid: the fitted ellipsoid (reported).
        snapped: its snapped copy, which the candidates are drawn from.
        parked: where the objects not yet placed wait, far from everything, shape (n, 3), m.
        heights: the centres' heights when ``planar``, shape (n,), m.
        quat: the objects' orientations, shape (n, 4), ``(w, x, y, z)``.
        planar: draw (x, y) and keep ``heights``, else draw 3-D centres.
        tolerance: largest accepted contact penetration of a placed object, m.
        limits: ``(max_attempts, max_restarts, max_growth_restarts)`` of :func:`perturb_frame`.

    """
    max_attempts, max_restarts, max_growth_restarts = limits
    n = frame.n_objects
    candidates = 0
    for restart in range(max_restarts + max_growth_restarts + 1):
        growth = 1.1 ** max(0, restart - max_restarts)
        sampler = Ellipsoid(snapped.center, snapped.radii * growth, snapped.rotation)
        positions = parked.copy()
        placed = 0
        attempts = 0
        while placed < n and attempts < max_attempts:
            attempts += 1
            candidates += 1
            point = sampler.sample(rng, 1)[0]
            trial = positions.copy()
            if planar:
                trial[placed] = (point[0], point[1], heights[placed])
            else:
                trial[placed] = point
            simulator.reset(_with_objects(frame, trial, quat))
            if _max_penetration(simulator, [placed]) <= tolerance:
                positions = trial
                placed += 1
                attempts = 0
        if placed == n:
            placement = _with_objects(frame, positions, quat)
            simulator.reset(placement)
            depth = _max_penetration(simulator, list(range(n)))
            return FramePerturbation(placement, ellipsoid, candidates, restart, growth, depth)
    raise EnergyMarginError(
        f"cannot place {n} objects without overlaps inside the ellipsoid of their centres "
        f"(radii {np.round(ellipsoid.radii, 4).tolist()} m) after {candidates} candidates"
    )


def _max_penetration(simulator: Any, objects: list[int]) -> float:
    """Deepest current interpenetration involving any of ``objects``, m (0.0 when none)."""
    depths = [depth for obj, other, depth in simulator.object_penetrations() if obj in objects or other in objects]
    return max(depths, default=0.0)


def _resting_height(frame: FrameState, simulator: Any, parked: np.ndarray, quat: np.ndarray) -> float:
    """Height at which an object of a planar task rests on the ground without penetrating it.

    The recorded heights sink into the soft ground by up to ~2 mm (pushing); one object is put at
    the frame's median height far from everything but the (flat, unbounded) ground, and lifted by
    the penetration measured there.
    """
    z = float(np.median(frame.object_pos[:, 2]))
    probe = parked.copy()
    probe[0] = (-_PARK_DISTANCE, -_PARK_DISTANCE, z)
    simulator.reset(_with_objects(frame, probe, quat))
    return z + _max_penetration(simulator, [0])


def _with_objects(frame: FrameState, positions: np.ndarray, quat: np.ndarray) -> FrameState:
    return FrameState(
        object_pos=positions,
        object_quat=quat,
        object_vel=np.zeros((frame.n_objects, 6)),
        robot_q=frame.robot_q,
        robot_v=frame.robot_v,
    )
