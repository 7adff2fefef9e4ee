"""What a controller minimises over predicted roll-outs: the task, a geometric heuristic, or margins.

Every cost sees the same :class:`Predictions` (the states at the end of each command period of k
sampled command sequences) and returns one number per sequence. The options:

``task``
    what a user writes first: the mean distance (m, over objects) of the objects to the success
    region at the horizon's end plus a quarter of its mean along the horizon, in units of the
    task's length scale; a small cost of departing from the task's scripted command; a large
    penalty for a state outside the task's bounds.
``heuristic``
    ``task`` plus the distance of objects outside the capture region built from each predicted
    state (the geometric baseline of ``evaluate``), the analogue of a contact-stability margin.
``margin``
    ``task`` minus ``margin_weight`` times the capture and success scores of the predicted end
    states, from a short energy-margin analysis (``margin_expansions`` expansions) of the
    ``margin_samples`` sequences with the lowest task cost; the others take the lowest scores
    among those analysed.
``learned``
    ``task`` minus ``margin_weight`` times a learned model's scores of every predicted end state.
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from energy_margin.analysis.frame import AnalyzerConfig, analyze_frame
from energy_margin.errors import EnergyMarginError
from energy_margin.sim import Simulator
from energy_margin.sim.base import ModelCommand
from energy_margin.tasks import Task
from energy_margin.tasks.base import MeasurableRegion
from energy_margin.world.state import FrameState

__all__ = [
    "COSTS",
    "CostContext",
    "CostFunction",
    "CostWeights",
    "MarginPredictor",
    "Predictions",
    "describe_costs",
    "get_cost",
    "heuristic_cost",
    "holding_task",
    "learned_cost",
    "margin_cost",
    "margin_scores",
    "task_cost",
]


@dataclass(frozen=True)
class Predictions:
    """The predicted states of k command sequences at the end of each of their P periods.

    P is the horizon H plus the controller's look-ahead (periods of the script's commands after
    the sampled ones).

    Attributes:
        object_pos: object positions, shape (k, P, n_objects, 3), m.
        object_quat: object orientations, shape (k, P, n_objects, 4).
        object_vel: object velocities, shape (k, P, n_objects, 6), m/s and rad/s.
        robot_q: end-effector coordinates, shape (k, P, n_robot_dofs), m or rad.
        robot_v: end-effector velocities, shape (k, P, n_robot_dofs), m/s or rad/s.
        commands: the sequences' deviations from the task's scripted command over the H sampled
            periods, shape (k, H, m), each component divided by its half range.
        forces: end-effector forces held at each sequence's end, shape (k, n_robot_dofs).
        targets: servo targets held at each sequence's end, shape (k, n_robot_dofs), or ``None``.
        end_time: episode time at the horizon's end, s.
        ctrl: actuator controls held at each sequence's end, shape (k, nu), or ``None``.

    """

    object_pos: np.ndarray
    object_quat: np.ndarray
    object_vel: np.ndarray
    robot_q: np.ndarray
    robot_v: np.ndarray
    commands: np.ndarray
    forces: np.ndarray
    targets: np.ndarray | None
    end_time: float
    ctrl: np.ndarray | None = None

    @property
    def n_samples(self) -> int:
        """Number of sequences k."""
        return int(self.object_pos.shape[0])

    def frame(self, sample: int, period: int = -1) -> FrameState:
        """The predicted state of sequence ``sample`` at the end of ``period`` (default: the last)."""
        return FrameState(
            self.object_pos[sample, period],
            self.object_quat[sample, period],
            self.object_vel[sample, period],
            self.robot_q[sample, period],
            self.robot_v[sample, period],
        )


class MarginPredictor(Protocol):
    """A learned margin: capture and success scores of frame states."""

    task_name: str

    def predict(self, task: Task, frames: Sequence[FrameState]) -> tuple[np.ndarray, np.ndarray]:
        """Capture and success scores in [0, 1], each shape (len(frames),)."""
        ...


@dataclass(frozen=True)
class CostWeights:
    """Weights of the cost terms (dimensionless: distances are in task length scales).

    Attributes:
        final: weight of the mean object distance to the success region at the horizon's end.
        running: weight of the same distance averaged along the horizon.
        deviation: weight of the mean squared normalised departure from the scripted command.
        out_of_bounds: penalty of a sequence that leaves the task's bounds.
        heuristic: weight of the distance outside the capture region (``heuristic``).
        margin: weight of the capture plus success score (``margin`` and ``learned``).

    """

    final: float = 1.0
    running: float = 0.25
    deviation: float = 0.05
    out_of_bounds: float = 100.0
    heuristic: float = 1.0
    margin: float = 2.0


class CostContext:
    """What a cost needs besides the predictions: the task, its length scale, analysis settings.

    Args:
        task: the task.
        length_scale: distance that counts as one unit of cost, m.
        weights: the terms' weights.
        friction: the controller's nominal Coulomb coefficient.
        drive: the trajectory's drive parameters (n_drive,).
        analysis_drive: drive parameters for the analysis of a predicted state, from the forces
            held at a sequence's end (a pushing analysis applies the drive as the pusher force).
        margin_expansions: expansions of each short analysis.
        margin_samples: sequences analysed per decision (the lowest task costs).
        seed_sequence: source of the analyses' seeds.
        model: the learned margin, for ``learned``.

    """

    def __init__(
        self,
        task: Task,
        *,
        length_scale: float,
        weights: CostWeights,
        friction: float,
        drive: np.ndarray,
        analysis_drive: Callable[[np.ndarray], np.ndarray],
        margin_expansions: int,
        margin_samples: int,
        seed_sequence: np.random.SeedSequence,
        model: MarginPredictor | None = None,
    ) -> None:
        self.task = task
        self.length_scale = length_scale
        self.weights = weights
        self.friction = friction
        self.drive = np.asarray(drive, dtype=float)
        self.analysis_drive = analysis_drive
        self.margin_expansions = margin_expansions
        self.margin_samples = margin_samples
        self.seed_sequence = seed_sequence
        self.model = model
        self._simulator: Simulator | None = None
        self.analyses = 0

    def simulator(self, n_objects: int) -> Simulator:
        """One simulator of the nominal scene, reused by every analysis."""
        if self._simulator is None:
            self._simulator = self.task.make_simulator(n_objects, self.friction, self.drive, "mujoco")
        return self._simulator


def _success_distance(task: Task, positions: np.ndarray, root: FrameState) -> np.ndarray:
    """Distance (m) of each object outside the success region (0 inside), shape (...)."""
    region = task.success_region_at(root)
    if not isinstance(region, MeasurableRegion):
        raise EnergyMarginError(f"task {task.name!r}: its success region measures no distance; it cannot be controlled")
    return np.maximum(0.0, -region.signed_distance(positions))


def task_cost(predictions: Predictions, context: CostContext) -> np.ndarray:
    """The ``task`` cost of every sequence, shape (k,)."""
    task, weights = context.task, context.weights
    root = predictions.frame(0)
    distance = _success_distance(task, predictions.object_pos, root) / context.length_scale  # (k, H, n)
    cost = weights.final * distance[:, -1].mean(axis=-1) + weights.running * distance.mean(axis=(1, 2))
    cost += weights.deviation * np.mean(predictions.commands**2, axis=(1, 2))
    for sample in range(predictions.n_samples):
        inside = all(
            task.within_bounds(predictions.object_pos[sample, period], predictions.object_vel[sample, period])
            for period in range(predictions.object_pos.shape[1])
        )
        if not inside:
            cost[sample] += weights.out_of_bounds
    return cost


def heuristic_cost(predictions: Predictions, context: CostContext) -> np.ndarray:
    """The ``heuristic`` cost: ``task`` plus the distance outside each predicted state's capture region."""
    cost = task_cost(predictions, context)
    task = context.task
    k, horizon = predictions.object_pos.shape[:2]
    outside = np.zeros(k)
    for sample in range(k):
        for period in range(horizon):
            frame = predictions.frame(sample, period)
            region = task.capture_region(frame)
            if not isinstance(region, MeasurableRegion):
                raise EnergyMarginError(f"task {task.name!r}: its capture region measures no distance")
            outside[sample] += float(np.mean(np.maximum(0.0, -region.signed_distance(frame.object_pos))))
    return cost + context.weights.heuristic * outside / (horizon * context.length_scale)


def holding_task(task: Task, force: np.ndarray, targets: np.ndarray | None, ctrl: np.ndarray | None = None) -> Task:
    """A copy of ``task`` whose end-effector holds ``force``, ``targets`` and ``ctrl`` instead of its script.

    The analysis of a predicted state then sees the controller's command, not the scripted one.
    """
    held = copy.copy(task)
    force = np.array(force, dtype=float)
    setattr(held, "robot_force", lambda state, rng=None: force)  # noqa: B010
    if targets is not None:
        fixed = np.array(targets, dtype=float)
        setattr(held, "robot_targets", lambda state, rng=None: fixed)  # noqa: B010
    if ctrl is not None:
        command = ModelCommand(ctrl=np.array(ctrl, dtype=float))
        setattr(held, "model_command", lambda drive, time: command)  # noqa: B010
    return held


def margin_scores(predictions: Predictions, context: CostContext, samples: Sequence[int]) -> np.ndarray:
    """Capture plus success score of the predicted end states of ``samples``, shape (len(samples),).

    The capture score is the tree's own (``capture_gate="none"``), with which the closed-loop
    results were measured: a planning cost, not a frame scored against its label.
    """
    config = AnalyzerConfig(expansions=context.margin_expansions, capture_gate="none")
    n_objects = predictions.object_pos.shape[2]
    seeds = context.seed_sequence.spawn(len(samples))
    totals = np.empty(len(samples))
    for slot, sample in enumerate(samples):
        targets = None if predictions.targets is None else predictions.targets[sample]
        ctrl = None if predictions.ctrl is None else predictions.ctrl[sample]
        task = holding_task(context.task, predictions.forces[sample], targets, ctrl)
        scores, _ = analyze_frame(
            task,
            predictions.frame(sample),
            friction=context.friction,
            drive=context.analysis_drive(predictions.forces[sample]),
            seed=int(seeds[slot].generate_state(1)[0]),
            config=config,
            start_time=predictions.end_time,
            simulator=context.simulator(n_objects),
        )
        totals[slot] = scores.capture_score + scores.success_score
        context.analyses += 1
    return totals


def margin_cost(predictions: Predictions, context: CostContext) -> np.ndarray:
    """The ``margin`` cost of every sequence, shape (k,)."""
    cost = task_cost(predictions, context)
    count = min(context.margin_samples, predictions.n_samples)
    analysed = np.argsort(cost, kind="stable")[:count]
    scores = np.full(predictions.n_samples, np.nan)
    scores[analysed] = margin_scores(predictions, context, analysed.tolist())
    scores[np.isnan(scores)] = np.min(scores[analysed])
    return cost - context.weights.margin * scores


def learned_cost(predictions: Predictions, context: CostContext) -> np.ndarray:
    """The ``learned`` cost of every sequence, shape (k,)."""
    if context.model is None:
        raise EnergyMarginError("the learned cost needs a model: pass `model`")
    cost = task_cost(predictions, context)
    frames = [predictions.frame(sample) for sample in range(predictions.n_samples)]
    capture, success = context.model.predict(context.task, frames)
    return cost - context.weights.margin * (np.asarray(capture) + np.asarray(success))


CostFunction = Callable[[Predictions, CostContext], np.ndarray]

#: The costs a controller can minimise, by name.
COSTS: dict[str, CostFunction] = {
    "task": task_cost,
    "heuristic": heuristic_cost,
    "margin": margin_cost,
    "learned": learned_cost,
}


def get_cost(name: str) -> CostFunction:
    """The cost ``name``; one clear error for an unknown one."""
    if name not in COSTS:
        raise EnergyMarginError(f"unknown cost {name!r}; choose one of {', '.join(COSTS)}")
    return COSTS[name]


def describe_costs() -> dict[str, Any]:
    """Cost names with their first docstring line."""
    return {name: (function.__doc__ or "").splitlines()[0] for name, function in COSTS.items()}
