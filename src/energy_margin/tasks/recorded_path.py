"""A roll-out's recorded robot path, carried in its drive parameters and followed during analysis.

A scene whose motion declares ``robot = "recorded"`` analyses recorded roll-outs (``record``,
``record --format robomimic``) whose commands are not known: during every propagation the robot
follows the path it was recorded on, from the analysed frame to the end of the roll-out, whatever
the objects do. Each roll-out's drive parameters carry its path after the scene's two scales
(:func:`path_drive`): ``P`` knots (``motion.path_points``), the recorded rows nearest ``P`` evenly
spaced times, each with the robot joints' positions and velocities:

``[time_scale, mass_scale, t (P,) s, q (P, n_joints) rad or m, v (P, n_joints) rad/s or m/s]``

Between knots the path is the cubic Hermite curve through the knots' positions and velocities;
before the first knot it keeps the first knot's velocity, after the last the last's.

The robot's joints carry an armature of :data:`RECORDED_ARMATURE` (kg m^2 or kg), heavy enough that
the objects' contacts, gravity and its actuators move it little off its path, and its velocities
are kept at each reset (a coasting robot); :func:`path_forces` gives the generalized forces that
change its velocities as the path's do over one command period: armature times the path's mean
acceleration ``(v(t + period) - v(t)) / period``. They depend on the time alone (not on the
state): :class:`PathForceTable` evaluates them once per roll-out at every time step of its path,
and a command at time t takes the row of the step nearest t, so a propagation batched through
``mujoco.rollout`` and one stepped one command at a time apply the same forces to the last bit
(and a command costs a lookup, not a curve evaluation).

:data:`RECORDED_ARMATURE` is a hundredth of a held robot's
(:data:`~energy_margin.sim.mujoco_model.STILL_ARMATURE`), chosen by replaying recorded sweeps along
their paths (``benchmarks/recorded_replay.py``, docs/howto/scenes.md): with a held robot's armature
the replayed objects strayed far further from their recording than with this one, whose arm stays
within about 0.01 rad of its path.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from energy_margin.errors import InvalidParameterError

__all__ = [
    "PATH_PREFIX",
    "RECORDED_ARMATURE",
    "PathForceTable",
    "nearest_rows",
    "path_drive",
    "path_drive_size",
    "path_forces",
    "path_velocities",
]

#: Drive parameters before the path: the motion's time scale and the objects' mass scale.
PATH_PREFIX = 2
#: Armature of the robot's joints while it follows a recorded path, kg m^2 or kg (see the module docstring).
RECORDED_ARMATURE = 1e6


def path_drive_size(points: int, n_joints: int) -> int:
    """Drive parameters of a scene following recorded paths of ``points`` knots of ``n_joints`` joints."""
    return PATH_PREFIX + points * (1 + 2 * n_joints)


def nearest_rows(time: np.ndarray, count: int) -> np.ndarray:
    """Row indices of ``time`` (n,) s nearest to ``count`` evenly spaced times from its first row to its last.

    A tie goes to the earlier row; one time is the last row's. ``record`` takes its frames and a
    recorded path its knots this way.
    """
    targets = np.linspace(time[0], time[-1], count) if count > 1 else np.array([time[-1]])
    rows = np.clip(np.searchsorted(time, targets), 1, time.size - 1) if time.size > 1 else np.zeros(count, int)
    if time.size > 1:
        nearer_before = np.abs(time[rows - 1] - targets) <= np.abs(time[rows] - targets)
        rows = np.where(nearer_before, rows - 1, rows)
    return rows.astype(int)


def path_drive(time: np.ndarray, q: np.ndarray, v: np.ndarray, *, points: int) -> np.ndarray:
    """The drive parameters of a recorded roll-out: scales of 1, then its path's knots.

    Args:
        time: the roll-out's times, shape (n,), s, increasing.
        q: the robot joints' positions at those times, shape (n, n_joints).
        v: their velocities, shape (n, n_joints).
        points: knots P, >= 2; a roll-out of fewer rows repeats its last row.

    Returns:
        Shape (:func:`path_drive_size`,).

    """
    time = np.asarray(time, dtype=float)
    q = np.asarray(q, dtype=float).reshape(time.size, -1)
    v = np.asarray(v, dtype=float).reshape(time.size, -1)
    if points < 2:
        raise InvalidParameterError("points", f"must be >= 2, got {points}")
    rows = np.unique(nearest_rows(time, points))
    rows = np.concatenate([rows, np.full(points - rows.size, rows[-1])])
    return np.concatenate([np.ones(PATH_PREFIX), time[rows], q[rows].ravel(), v[rows].ravel()])


def _knots(drives: np.ndarray, n_joints: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Knot times (k, P), positions and velocities (k, P, n_joints) of drive rows (k, n_drive)."""
    drives = np.asarray(drives, dtype=float)
    k = drives.shape[0]
    points = (drives.shape[1] - PATH_PREFIX) // (1 + 2 * n_joints)
    if drives.shape[1] != path_drive_size(points, n_joints) or points < 2:
        raise InvalidParameterError(
            "drive", f"holds {drives.shape[1]} parameters, not a recorded path of {n_joints} joints"
        )
    at = PATH_PREFIX
    times = drives[:, at : at + points]
    q = drives[:, at + points : at + points * (1 + n_joints)].reshape(k, points, n_joints)
    v = drives[:, at + points * (1 + n_joints) :].reshape(k, points, n_joints)
    return times, q, v


def path_velocities(drives: np.ndarray, times: np.ndarray, n_joints: int) -> np.ndarray:
    """The path's joint velocities at ``times`` (k,) s of drive rows (k, n_drive): shape (k, n_joints).

    The derivative of the cubic Hermite curve through the knots; the first (last) knot's velocity
    before (after) the path.
    """
    knot_t, knot_q, knot_v = _knots(drives, n_joints)
    k, points = knot_t.shape
    times = np.asarray(times, dtype=float)
    rows = np.arange(k)
    # The segment of each time: the last knot at or before it (repeated knots only end a path).
    lower = np.clip((knot_t <= times[:, None]).sum(axis=1) - 1, 0, points - 2)
    upper = lower + 1
    t0, t1 = knot_t[rows, lower], knot_t[rows, upper]
    span = t1 - t0
    inside = (times > knot_t[:, 0]) & (times < knot_t[:, -1]) & (span > 0)
    s = np.where(inside, (times - t0) / np.where(span > 0, span, 1.0), 0.0)[:, None]
    h = np.where(span > 0, span, 1.0)[:, None]
    q0, q1 = knot_q[rows, lower], knot_q[rows, upper]
    v0, v1 = knot_v[rows, lower], knot_v[rows, upper]
    hermite = (
        (6 * s**2 - 6 * s) * q0 / h
        + (3 * s**2 - 4 * s + 1) * v0
        + (6 * s - 6 * s**2) * q1 / h
        + (3 * s**2 - 2 * s) * v1
    )
    first = times[:, None] <= knot_t[:, :1]
    return np.where(inside[:, None], hermite, np.where(first, knot_v[:, 0], knot_v[:, -1]))


def path_forces(drives: np.ndarray, times: np.ndarray, *, n_joints: int, period: float, armature: float) -> np.ndarray:
    """Generalized forces on the robot joints that follow the path over one command period.

    Args:
        drives: each row's drive parameters, shape (k, n_drive) (:func:`path_drive`).
        times: each row's time, shape (k,), s.
        n_joints: the robot's hinge and slide joints.
        period: seconds the forces are held, > 0.
        armature: the joints' armature, kg m^2 or kg.

    Returns:
        Shape (k, n_joints): N m or N.

    """
    times = np.asarray(times, dtype=float)
    now = path_velocities(drives, times, n_joints)
    later = path_velocities(drives, times + period, n_joints)
    return armature * (later - now) / period


@dataclass(frozen=True)
class PathForceTable:
    """A recorded path's forces (:func:`path_forces`) at every time step from its first knot to its end.

    Attributes:
        first_step: the time step (time / dt, rounded) of the table's first row.
        forces: shape (n_steps, n_joints): row i holds the forces at ``(first_step + i) * dt``; the
            last row is past the last knot plus one command period, where the path's velocity is
            constant and the forces are zero.
        dt: the time step, s.

    """

    first_step: int
    forces: np.ndarray
    dt: float

    @classmethod
    def of(cls, drive: np.ndarray, *, n_joints: int, dt: float, hold_steps: int, armature: float) -> PathForceTable:
        """The table of one roll-out's drive parameters (:func:`path_drive`), commands held ``hold_steps`` steps."""
        drive = np.asarray(drive, dtype=float)
        knot_t = _knots(drive[None], n_joints)[0][0]
        first, last = round(knot_t[0] / dt), round(knot_t[-1] / dt) + hold_steps
        steps = np.arange(first, last + 1)
        forces = path_forces(np.broadcast_to(drive, (steps.size, drive.size)), steps * dt, n_joints=n_joints,
                             period=hold_steps * dt, armature=armature)  # fmt: skip
        return cls(first_step=first, forces=forces, dt=dt)

    def at(self, times: np.ndarray) -> np.ndarray:
        """The forces at ``times`` (k,) s: the rows of the steps nearest them, shape (k, n_joints).

        Times before the first knot take the first row (a frame lies within its recording).
        """
        steps = np.rint(np.asarray(times, dtype=float) / self.dt).astype(np.int64) - self.first_step
        return self.forces[np.clip(steps, 0, self.forces.shape[0] - 1)]

    def row(self, time: float) -> np.ndarray:
        """:meth:`at` of one time (s), the same row: shape (n_joints,)."""
        step = round(time / self.dt) - self.first_step  # half to even, as numpy's rint
        return self.forces[min(max(step, 0), self.forces.shape[0] - 1)]
