"""The bounds of a task's analysis: its sane states (a box, a speed bound) and its perturbation ranges.

One :class:`StateBox` per task serves twice: a tree rejects every reached state outside it
(:meth:`Task.within_bounds`), and no frame outside it becomes data (``generate``, ``record``, the
wrappers' recorder and ``check``, :mod:`energy_margin.data.physical`). Its :class:`WrenchLimits`
bound the wrenches the analyzer perturbs the objects with.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from energy_margin.errors import Constraint, InvalidParameterError, check_fields, constrained_required

if TYPE_CHECKING:
    import mujoco

__all__ = ["OUTSIDE", "TOO_FAST", "StateBox", "Violation", "WrenchLimits", "box_around_model"]

#: Kinds of :class:`Violation`.
OUTSIDE = "outside the bounds"
TOO_FAST = "too fast"


@dataclass(frozen=True)
class Violation:
    """One object of one state outside its task's :class:`StateBox`.

    Attributes:
        object: the object's index.
        kind: :data:`OUTSIDE` or :data:`TOO_FAST`.
        value: the object's position (3,), m, or its speed, m/s.
        message: the violation in words, with the value and the bound.
    """

    object: int
    kind: str
    value: tuple[float, ...]
    message: str


@dataclass(frozen=True)
class StateBox:
    """Objects' positions between ``low`` and ``high`` and speeds at most ``max_speed``.

    Attributes:
        low: lowest position of an object's origin on x, y, z, shape (3,), m (``-inf``: none).
        high: highest position, shape (3,), m (``inf``: none).
        max_speed: largest linear speed of an object (the norm of its velocity), m/s.
        source: where the bounds come from, in words (e.g. "the scene file's [bounds]").
    """

    # low and high are checked together (three bounds each, low < high; an infinite bound is none).
    low: tuple[float, float, float]
    high: tuple[float, float, float]
    max_speed: float = constrained_required(Constraint("float", minimum=0.0, exclusive_minimum=True))
    source: str = ""

    def __post_init__(self) -> None:
        """Check the box: three bounds per side, low < high, a positive speed."""
        if len(self.low) != 3 or len(self.high) != 3:
            raise InvalidParameterError("low", f"and high must hold three bounds each, got {self.low} and {self.high}")
        if any(not a < b for a, b in zip(self.low, self.high, strict=True)):
            raise InvalidParameterError("low", f"must be below high on every axis, got {self.low} and {self.high}")
        check_fields(self)
        object.__setattr__(self, "_low", np.asarray(self.low, dtype=float))
        object.__setattr__(self, "_high", np.asarray(self.high, dtype=float))

    def contains(self, object_pos: np.ndarray, object_vel: np.ndarray) -> bool:
        """Whether every object lies inside the box and moves no faster than ``max_speed``.

        Args:
            object_pos: positions, shape (n_objects, 3), m.
            object_vel: velocities, linear first, shape (n_objects, 6) (or (n_objects, 3)), m/s.
        """
        low: np.ndarray = self._low  # type: ignore[attr-defined]
        high: np.ndarray = self._high  # type: ignore[attr-defined]
        if (object_pos < low).any() or (object_pos > high).any():
            return False
        linear = object_vel[:, :3]
        return bool(np.einsum("ij,ij->i", linear, linear).max() <= self.max_speed**2)

    def violations(self, object_pos: np.ndarray, object_vel: np.ndarray) -> list[Violation]:
        """Every object outside the box or faster than ``max_speed`` (NaN counts as outside), by object.

        Args:
            object_pos: positions, shape (n_objects, 3), m.
            object_vel: velocities, linear first, shape (n_objects, 6), m/s.
        """
        low: np.ndarray = self._low  # type: ignore[attr-defined]
        high: np.ndarray = self._high  # type: ignore[attr-defined]
        found = []
        speeds = np.linalg.norm(object_vel[:, :3], axis=1)
        for index, (pos, speed) in enumerate(zip(object_pos, speeds, strict=True)):
            if not (np.all(pos >= low) and np.all(pos <= high)):
                found.append(
                    Violation(
                        index,
                        OUTSIDE,
                        tuple(float(x) for x in pos),
                        f"object {index} at {_point(pos)} m lies outside the bounds {_point(low)} to "
                        f"{_point(high)} m ({self.source or 'the task'})",
                    )
                )
            if not speed <= self.max_speed:
                found.append(
                    Violation(
                        index,
                        TOO_FAST,
                        (float(speed),),
                        f"object {index} moves at {_number(speed)} m/s, faster than {_number(self.max_speed)} m/s "
                        f"({self.source or 'the task'})",
                    )
                )
        return found


def _number(value: float) -> str:
    return f"{value:.4g}"


def _point(values: np.ndarray) -> str:
    return "(" + ", ".join(_number(float(v)) for v in values) + ")"


def box_around_model(model: mujoco.MjModel, margin: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """The axis-aligned box around every bounded geom of ``model``, ``margin`` larger on every side.

    Each geom counts with its bounding sphere, at the model's reference configuration and at every
    keyframe; planes (unbounded) do not count.

    Args:
        model: a compiled model.
        margin: added on every side, m.

    Returns:
        ``(low, high)``, each (3,), m.
    """
    import mujoco

    data = mujoco.MjData(model)
    bounded = (model.geom_type != mujoco.mjtGeom.mjGEOM_PLANE) & (model.geom_rbound > 0)
    lows, highs = [], []
    for key in range(-1, int(model.nkey)):
        if key < 0:
            mujoco.mj_resetData(model, data)
        else:
            mujoco.mj_resetDataKeyframe(model, data, key)
        mujoco.mj_kinematics(model, data)
        centres = data.geom_xpos[bounded]
        radii = model.geom_rbound[bounded][:, None]
        if centres.size:
            lows.append((centres - radii).min(axis=0))
            highs.append((centres + radii).max(axis=0))
    if not lows:
        return (-margin,) * 3, (margin,) * 3
    low = np.min(lows, axis=0) - margin
    high = np.max(highs, axis=0) + margin
    return tuple(float(x) for x in low), tuple(float(x) for x in high)


@dataclass(frozen=True)
class WrenchLimits:
    """Uniform perturbation ranges of one analysis.

    Attributes:
        max_wrench: per-object bound on |force| (N) and |torque| (N m) per world axis, shape
            (n_objects, 6); a zero entry is never perturbed.
        max_duration: longest propagation, seconds.

    """

    max_wrench: np.ndarray
    max_duration: float

    @property
    def control_dimension(self) -> int:
        """Number of perturbed wrench components (sets the duration bias)."""
        return int(np.count_nonzero(self.max_wrench))
