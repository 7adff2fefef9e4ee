"""What a MuJoCo roll-out went through: the engine's warnings, and energy gained without work.

MuJoCo counts every warning it raises in ``MjData.warning`` (and restarts a blown-up simulation
from the model's reference state by itself), so a roll-out can end quietly after it went wrong:
:func:`raised_warnings` reads the counters. :class:`EnergyAudit` follows the model's mechanical
energy (kinetic, gravitational and spring) against the work done on it from outside: actuators,
applied forces, gravity compensation and equality constraints (a mocap body drives a robot
through one). Damping, friction and contacts only take energy out of a sound simulation, so a
gain beyond the work done is energy from nothing: the mark of a blow-up, even one that leaves the
objects inside their bounds (an object spinning up in place).
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

from energy_margin.compat import has_warning_hook

#: The warnings that mean a roll-out went wrong, with what each means. ``mjWARN_VGEOMFULL``
#: (the visual geom buffer is full) says nothing about the physics and is left out.
PHYSICS_WARNINGS: dict[str, str] = {
    "mjWARN_INERTIA": "an inertia matrix too close to singular",
    "mjWARN_CONTACTFULL": "a full contact buffer, contacts dropped",
    "mjWARN_CNSTRFULL": "a full constraint buffer, constraints dropped",
    "mjWARN_BADQPOS": "a NaN, infinite or huge position, and reset the simulation",
    "mjWARN_BADQVEL": "a NaN, infinite or huge velocity, and reset the simulation",
    "mjWARN_BADQACC": "a NaN, infinite or huge acceleration, and reset the simulation",
    "mjWARN_BADCTRL": "a NaN, infinite or huge control",
}

#: The roll-out array of :func:`warning_numbers` per row (``(n, 7)``), as the wrappers record it.
WARNINGS_ARRAY = "mujoco_warnings"


def raised_warnings(data: mujoco.MjData) -> dict[str, int]:
    """The physics warnings MuJoCo raised on ``data`` since its last reset: name -> how many times."""
    raised = {}
    for name in PHYSICS_WARNINGS:
        number = int(data.warning[getattr(mujoco.mjtWarning, name)].number)
        if number:
            raised[name] = number
    return raised


#: The indices of :data:`PHYSICS_WARNINGS` among MuJoCo's warnings.
_PHYSICS_WARNING_INDICES = np.array([int(getattr(mujoco.mjtWarning, name)) for name in PHYSICS_WARNINGS])


def warning_numbers(data: mujoco.MjData) -> np.ndarray:
    """How many times MuJoCo raised each of :data:`PHYSICS_WARNINGS` on ``data`` since its reset, shape (7,)."""
    return np.asarray(data.warning.number, dtype=int)[_PHYSICS_WARNING_INDICES]


def describe_warnings(raised: dict[str, int]) -> str:
    """:func:`raised_warnings` in words, e.g. ``"MuJoCo warned mjWARN_BADQACC 2x: a NaN, ..."``."""
    parts = [f"{name} {count}x: {PHYSICS_WARNINGS.get(name, 'a warning')}" for name, count in raised.items()]
    return "MuJoCo warned " + "; ".join(parts)


#: File of :class:`WarningLog` in a run's directory.
LOG_FILE = "mujoco_log.txt"


class WarningLog:
    """MuJoCo's warning messages of this process, kept for the run's directory.

    Without it MuJoCo appends every warning to ``MUJOCO_LOG.TXT`` in the working directory (and
    prints it). Inside ``with WarningLog() as log:`` the messages go to ``log.messages`` (worker
    processes forked inside keep their own, unwritten, copy), and :meth:`write` appends them to
    :data:`LOG_FILE` in a directory. MuJoCo releases without the hook keep their own behaviour.
    """

    #: Messages kept; later ones are only counted (:attr:`count`).
    MAX_MESSAGES = 1000

    def __init__(self) -> None:
        self.messages: list[str] = []
        self.count = 0
        self._previous: object = None

    def _add(self, message: str) -> None:
        self.count += 1
        if len(self.messages) < self.MAX_MESSAGES:
            self.messages.append(message)

    def __enter__(self) -> WarningLog:
        """Take MuJoCo's warnings from here on."""
        if has_warning_hook():
            self._previous = mujoco.get_mju_user_warning()
            mujoco.set_mju_user_warning(self._add)
        return self

    def __exit__(self, *exc: object) -> None:
        """Give MuJoCo's warnings back to whoever had them."""
        if has_warning_hook():
            mujoco.set_mju_user_warning(self._previous)

    def write(self, directory: Path) -> Path | None:
        """Append the messages to ``directory/mujoco_log.txt`` when both exist; its path, or ``None``."""
        if not self.messages or not directory.is_dir():
            return None
        path = directory / LOG_FILE
        with path.open("a", encoding="utf-8") as stream:
            stream.writelines(f"{message}\n" for message in self.messages)
        return path


class EnergyAudit:
    """The mechanical energy of a roll-out on ``model``/``data`` against the work done on it.

    Build it at the roll-out's start, call :meth:`after_step` after every ``mj_step``, and read
    :meth:`gain` whenever: the energy gained since the start beyond the work done from outside, J.

    Args:
        model: the compiled model.
        data: the roll-out's data, holding its start state (after ``mj_forward``).
    """

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        self.model = model
        self.data = data
        self._scratch = mujoco.MjData(model)
        self._equality_rows = mujoco.mjtConstraint.mjCNSTR_EQUALITY
        # Gravity compensation does work on the robot; releases without the separate array keep it in qfrc_passive.
        self._gravcomp = bool(np.any(model.body_gravcomp != 0)) and hasattr(data, "qfrc_gravcomp")
        self._qfrc = np.zeros(model.nv)
        self._qvel = data.qvel.copy()
        self.work = 0.0
        self.start_energy = self.energy()

    def energy(self) -> float:
        """The model's mechanical energy in ``data``'s current state: kinetic, gravitational and springs, J."""
        model, scratch = self.model, self._scratch
        scratch.qpos[:] = self.data.qpos
        scratch.qvel[:] = self.data.qvel
        scratch.mocap_pos[:] = self.data.mocap_pos
        scratch.mocap_quat[:] = self.data.mocap_quat
        mujoco.mj_fwdPosition(model, scratch)
        mujoco.mj_energyPos(model, scratch)
        mujoco.mj_energyVel(model, scratch)
        return float(scratch.energy[0] + scratch.energy[1])

    def after_step(self) -> None:
        """Add the work done on the model during the step just taken (forces of the step, mean velocity)."""
        model, data = self.model, self.data
        velocity = 0.5 * (self._qvel + data.qvel)
        force = data.qfrc_actuator + data.qfrc_applied
        if self._gravcomp:
            force = force + data.qfrc_gravcomp
        pushed = np.flatnonzero(np.any(data.xfrc_applied != 0, axis=1))
        if pushed.size:
            self._qfrc[:] = 0.0
            for body in pushed:
                wrench = data.xfrc_applied[body]
                mujoco.mj_applyFT(model, data, wrench[:3], wrench[3:], data.xipos[body], int(body), self._qfrc)
            force = force + self._qfrc
        with np.errstate(all="ignore"):  # a blown-up step's power is not finite: the gain says so
            power = float(force @ velocity)
            if data.nefc:
                rows = data.efc_type[: data.nefc] == self._equality_rows
                if rows.any():
                    power += float(data.efc_force[: data.nefc][rows] @ data.efc_vel[: data.nefc][rows])
            self.work += power * float(model.opt.timestep)
        self._qvel[:] = data.qvel

    def gain(self) -> float:
        """Energy gained since the start beyond the work done from outside, J.

        Above 0: energy from nothing; NaN after a blow-up.
        """
        with np.errstate(all="ignore"):
            return self.energy() - self.start_energy - self.work


__all__ = [
    "LOG_FILE",
    "PHYSICS_WARNINGS",
    "WARNINGS_ARRAY",
    "EnergyAudit",
    "WarningLog",
    "describe_warnings",
    "raised_warnings",
    "warning_numbers",
]
