"""The camera and colours of rendered frames: views fitted to points, viridis, the likelihood scale."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from energy_margin.errors import InvalidParameterError

if TYPE_CHECKING:
    from energy_margin.world.scene import Scene

__all__ = [
    "CAPTURE_RGBA",
    "LIKELIHOOD_DECADES",
    "SUCCESS_RGBA",
    "View",
    "fit_view",
    "likelihood_scale",
    "near_objects",
    "scene_view",
    "viridis",
]


#: Colours of the drawn regions (RGBA, translucent).
CAPTURE_RGBA = (0.12, 0.47, 0.71, 0.22)
SUCCESS_RGBA = (0.58, 0.25, 0.78, 0.22)
#: Likelihoods below ``max / 10**LIKELIHOOD_DECADES`` get the colour of the lowest.
LIKELIHOOD_DECADES = 6.0


# Viridis at 9 evenly spaced stops (matplotlib's table), interpolated linearly.
_VIRIDIS = np.array(
    [
        (0.267004, 0.004874, 0.329415),
        (0.282623, 0.140926, 0.457517),
        (0.229739, 0.322361, 0.545706),
        (0.172719, 0.448791, 0.557885),
        (0.127568, 0.566949, 0.550556),
        (0.134692, 0.658636, 0.517649),
        (0.266941, 0.748751, 0.440573),
        (0.477504, 0.821444, 0.318195),
        (0.993248, 0.906157, 0.143936),
    ]
)


def viridis(values: np.ndarray) -> np.ndarray:
    """Viridis colours (..., 3) in [0, 1] of values (...) in [0, 1] (clipped)."""
    scaled = np.clip(np.asarray(values, dtype=float), 0.0, 1.0) * (len(_VIRIDIS) - 1)
    low = np.minimum(np.floor(scaled).astype(int), len(_VIRIDIS) - 2)
    weight = (scaled - low)[..., None]
    return _VIRIDIS[low] * (1.0 - weight) + _VIRIDIS[low + 1] * weight


def likelihood_scale(likelihoods: np.ndarray) -> np.ndarray:
    """Where each likelihood (M,) lies on the colour scale, in [0, 1]: log10, the top ``LIKELIHOOD_DECADES`` decades."""
    values = np.asarray(likelihoods, dtype=float)
    top = np.log10(max(float(values.max()), 1e-300))
    logs = np.log10(np.maximum(values, 1e-300))
    return np.clip((logs - (top - LIKELIHOOD_DECADES)) / LIKELIHOOD_DECADES, 0.0, 1.0)


@dataclass(frozen=True)
class View:
    """A free camera looking at a point.

    Attributes:
        lookat: the point looked at, shape (3,), m.
        distance: from the camera to ``lookat``, m.
        azimuth: heading of the camera, degrees (90 looks along +y).
        elevation: pitch, degrees (negative looks down).

    """

    lookat: tuple[float, float, float]
    distance: float
    azimuth: float = 90.0
    elevation: float = -55.0


def fit_view(points: np.ndarray, *, elevation: float, azimuth: float = 90.0, fovy: float = 45.0) -> View:
    """A view of ``elevation`` and ``azimuth`` (degrees) that holds every point (n, 3), m, with a margin."""
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    points = points[np.all(np.isfinite(points), axis=1)]
    if points.size == 0:
        raise InvalidParameterError("points", "must hold at least one finite point")
    low, high = points.min(axis=0), points.max(axis=0)
    centre = 0.5 * (low + high)
    radius = max(float(np.linalg.norm(high - low)) / 2.0, 0.02)
    distance = 1.15 * radius / np.sin(np.radians(fovy) / 2.0)
    lookat = (float(centre[0]), float(centre[1]), float(centre[2]))
    return View(lookat, float(distance), azimuth, elevation)


def near_objects(points: np.ndarray, object_pos: np.ndarray) -> np.ndarray:
    """The ``points`` (n, 3) that lie near the objects (m, 3), m: what a picture of them frames.

    Near: within 0.3 m plus twice the objects' spread of their centre. A pusher or a scoop is
    there; a third-party arm's base, upper links and floor are not, and framing them left the
    objects a few pixels wide.
    """
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    objects = np.asarray(object_pos, dtype=float).reshape(-1, 3)
    centre = objects.mean(axis=0)
    spread = float(np.max(np.linalg.norm(objects - centre, axis=1)))
    keep = np.linalg.norm(points - centre, axis=1) <= 0.3 + 2.0 * spread
    return points[keep]


def scene_view(scene: Scene, points: np.ndarray, *, fovy: float = 45.0) -> View:
    """The view of a scene's frame: from above for planar (upright) objects, from the side otherwise."""
    planar = scene.object_motion == "upright"
    if planar:
        return fit_view(points, elevation=-55.0, fovy=fovy)
    view = fit_view(points, elevation=-25.0, azimuth=60.0, fovy=fovy)
    # Further back: the gripper's regions are open upwards and would fill the picture.
    return View(view.lookat, 1.4 * view.distance, view.azimuth, view.elevation)
