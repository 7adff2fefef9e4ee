"""Physical sanity of the frames that become data: no impossible state is ever labelled.

Two kinds of test. On frames alone, in any dataset (``check``, and ``generate`` and ``record``
before they write): each object inside its task's frame box (a
:class:`~energy_margin.tasks.state_box.StateBox`: the scene file's ``[bounds]``, or a box around
the model) and no faster than its speed bound (:func:`state_problems`, :func:`frame_violations`).
During a roll-out this package steps (``generate``), :class:`RolloutWatch` also reads every
warning MuJoCo raised and audits the energy (:mod:`energy_margin.sim.mujoco_audit`); a recorded
roll-out brings MuJoCo's warning counts along when the wrappers recorded it. Overlapping objects
are the third test (:mod:`energy_margin.data.validation`); :class:`DrawTally` stops a generation
whose draws mostly fail, with :data:`LIKELY_FIX`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from energy_margin.data.dataset import FRAMES_FILE, Dataset, Problem
from energy_margin.sim.base import CompiledModel, Simulator
from energy_margin.tasks.base import Task
from energy_margin.tasks.state_box import OUTSIDE, StateBox, Violation
from energy_margin.world.state import FrameState

#: A roll-out whose energy grew by more than this beyond the work done on it, J, per kilogram
#: of the model's moving mass, and by more than :data:`ENERGY_FLOOR`, gained energy from nothing.
#: Sound roll-outs lose energy (on the built-in tasks and every example, generation seed 100, the
#: largest change beyond the work done was a loss; benchmarks/physical_sanity.py); a blown-up
#: one gains orders of magnitude more than this.
ENERGY_PER_KG = 1.0
#: Smallest energy gain flagged, J.
ENERGY_FLOOR = 1.0
_MAX_PER_KIND = 5


def frame_violations(box: StateBox, frame: FrameState) -> list[Violation]:
    """The objects of ``frame`` outside ``box`` or too fast (a non-finite value counts as outside)."""
    return box.violations(np.asarray(frame.object_pos, dtype=float), np.asarray(frame.object_vel, dtype=float))


def state_problems(dataset: Dataset) -> list[Problem]:
    """Frames of ``dataset`` with an object outside its task's frame box or faster than its bound.

    One problem per object and kind, naming the trajectory, the frame, the object and the value:
    the first five of each kind, then one that counts the rest. Non-finite values are left to the
    array checks.
    """
    try:
        box = dataset.task.frame_box
    except (ValueError, OverflowError, FloatingPointError, ZeroDivisionError) as error:
        return [Problem("dataset.json", "task_config", "", f"cannot build the task's bounds ({error})")]
    positions, velocities = dataset.arrays["object_pos"], dataset.arrays["object_vel"]
    finite = np.isfinite(positions).all(axis=(2, 3)) & np.isfinite(velocities).all(axis=(2, 3))
    problems: list[Problem] = []
    counts = {"object_pos": 0, "object_vel": 0}
    for trajectory, frame in zip(*np.nonzero(finite), strict=True):
        pos, vel = positions[trajectory, frame], velocities[trajectory, frame]
        if box.contains(pos, vel):
            continue
        for violation in box.violations(pos, vel):
            field = "object_pos" if violation.kind == OUTSIDE else "object_vel"
            counts[field] += 1
            if counts[field] <= _MAX_PER_KIND:
                where = f"trajectory {trajectory}, frame {frame}, object {violation.object}"
                problems.append(Problem(FRAMES_FILE, field, where, violation.message))
    for field, what in (("object_pos", "outside the bounds"), ("object_vel", "too fast")):
        if counts[field] > _MAX_PER_KIND:
            more = counts[field] - _MAX_PER_KIND
            problems.append(Problem(FRAMES_FILE, field, "", f"{more} more object(s) {what} in other frames"))
    return problems


class RolloutWatch:
    """Watches one roll-out of ``simulator`` from its current state: warnings, energy, frames.

    Call :meth:`after_step` after every physics step (or every environment step, for a roll-out
    stepped elsewhere: the energy audit then only runs where it saw every step) and :meth:`frame`
    at every recorded frame; :meth:`problems` lists what went wrong, in words.

    Args:
        simulator: the roll-out's simulator, reset to its start.
        box: the task's state box.
        audit_energy: follow the energy step by step (MuJoCo simulators only).
    """

    def __init__(self, simulator: Simulator, box: StateBox, *, audit_energy: bool = True) -> None:
        self.simulator = simulator
        self.box = box
        self._model_data = simulator if isinstance(simulator, CompiledModel) else None
        self._audit = None
        if audit_energy and self._model_data is not None:
            from energy_margin.sim.mujoco_audit import EnergyAudit

            self._audit = EnergyAudit(self._model_data.model, self._model_data.data)
        self._found: list[str] = []
        self._frames = 0

    def after_step(self) -> None:
        """Account for the physics step just taken."""
        if self._audit is not None:
            self._audit.after_step()

    def frame(self, frame: FrameState) -> None:
        """Test a recorded frame: inside the state box, no faster than its bound."""
        violations = frame_violations(self.box, frame)
        if violations:
            self._found.append(f"frame {self._frames}: {violations[0].message}")
        self._frames += 1

    def energy_limit(self) -> float:
        """The largest energy gain accepted, J (:data:`ENERGY_PER_KG` of the moving mass, at least the floor)."""
        if self._model_data is None:
            return float("inf")
        model = self._model_data.model
        moving = float(np.sum(model.body_mass[model.body_weldid != 0]))
        return max(ENERGY_FLOOR, ENERGY_PER_KG * moving)

    def energy_gain(self) -> float | None:
        """Energy gained so far beyond the work done, J (``None`` without an audit)."""
        return None if self._audit is None else self._audit.gain()

    def problems(self) -> list[str]:
        """What went wrong in the roll-out so far, one sentence each (empty: nothing)."""
        found = list(self._found[:1])
        if self._model_data is not None:
            from energy_margin.sim.mujoco_audit import describe_warnings, raised_warnings

            raised = raised_warnings(self._model_data.data)
            if raised:
                found.insert(0, describe_warnings(raised))
            if self._audit is not None:
                gain, limit = self._audit.gain(), self.energy_limit()
                if not gain <= limit:
                    found.append(
                        f"the simulation gained {gain:.4g} J without work done on it (more than {limit:.3g} J)"
                    )
        elif self.simulator.diverged():
            found.insert(0, "the simulation diverged (a non-finite state)")
        return found


def count_reasons(reasons: Sequence[str]) -> str:
    """The most common kind among ``reasons`` (their text before the first colon or parenthesis)."""
    kinds: dict[str, int] = {}
    for reason in reasons:
        kind = reason_kind(reason)
        kinds[kind] = kinds.get(kind, 0) + 1
    return max(kinds, key=lambda kind: kinds[kind]) if kinds else ""


def reason_kind(reason: str) -> str:
    """The kind of a refused draw's reason: ``warning``, ``bounds``, ``speed``, ``energy`` or ``overlap``."""
    if reason.startswith("MuJoCo warned") or reason.startswith("the simulation diverged"):
        return "warning"
    if "outside the bounds" in reason:
        return "bounds"
    if "m/s, faster than" in reason:
        return "speed"
    if "without work" in reason:
        return "energy"
    return "overlap"


#: Generation stops once this many draws failed and they are most of the draws so far: the
#: scene, not bad luck, is at fault.
MOST_DRAWS_FAIL = 10
#: What to change when most draws fail, by the kind of failure (:func:`~energy_margin.data.physical.reason_kind`).
LIKELY_FIX = {
    "warning": "the simulation is unstable: a smaller time step (<option timestep>), another integrator "
    "(implicit, RK4) or softer contacts in the model may keep it stable",
    "energy": "the simulation creates energy: a smaller time step (<option timestep>), another integrator "
    "(implicit, RK4) or softer contacts in the model may keep it stable",
    "bounds": "objects leave the scene's [bounds]: widen [bounds] if they belong there; objects thrown far "
    "away mean an unstable simulation (a smaller time step, another integrator such as implicit)",
    "speed": "objects move faster than bounds.max_speed: raise it if they really do; otherwise the simulation "
    "is unstable (a smaller time step, another integrator such as implicit)",
    "overlap": "objects overlap deeper than the dataset check allows: use fewer objects or a larger workspace",
}


class DrawTally:
    """Draws made and refused so far in one generation, to stop when most draws fail."""

    def __init__(self) -> None:
        self.draws = 0
        self.reasons: list[str] = []

    def add(self, reason: str | None) -> None:
        """Count one draw, refused for ``reason`` (``None``: accepted)."""
        self.draws += 1
        if reason is not None:
            self.reasons.append(reason)

    def stop_reason(self, task: Task) -> str | None:
        """Why generation should stop, or ``None`` while most draws succeed."""
        failed = len(self.reasons)
        if failed < MOST_DRAWS_FAIL or 2 * failed <= self.draws:
            return None
        kind = count_reasons(self.reasons)
        example = next(reason for reason in reversed(self.reasons) if reason_kind(reason) == kind)
        return (
            f"cannot generate {task.name} trajectories: {failed} of {self.draws} draws failed, most for the same "
            f"cause (the last: {example}); {LIKELY_FIX[kind]}"
        )


__all__ = [
    "ENERGY_FLOOR",
    "ENERGY_PER_KG",
    "LIKELY_FIX",
    "MOST_DRAWS_FAIL",
    "DrawTally",
    "RolloutWatch",
    "count_reasons",
    "frame_violations",
    "reason_kind",
    "state_problems",
]
