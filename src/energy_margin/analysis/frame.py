"""Energy margins of one frame (Algorithm 1): grow a tree from the state and score it.

``analyze_frame`` scores one state; ``analyze_frames`` scores the frames of one roll-out with
their trees grown in lockstep (an engine whose batched propagations run on a device);
:class:`FrameAnalyzer` scores the frames of one dataset by index, reusing simulators, with
per-frame seeds from :func:`frame_seeds` so that the scores do not depend on the number of
workers, on the order in which frames finish, or on which frames grow together.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Iterator, Sequence
from typing import Any

import numpy as np

from energy_margin.analysis.config import ANALYSIS_MODELS, DEVICES, AnalyzerConfig, FrameScores
from energy_margin.analysis.continuation import continued_success, continued_successes_together
from energy_margin.analysis.convergence import (
    CONVERGE_RULES,
    EitherStop,
    ScoresConverged,
    field_membership,
    frame_seeds,
    score_field,
)
from energy_margin.analysis.scores import gate_capture
from energy_margin.data.dataset import Dataset
from energy_margin.errors import InvalidParameterError
from energy_margin.planning import CostField, grow_tree, grow_trees_together
from energy_margin.planning.costs import make_cost_model
from energy_margin.planning.density import make_features
from energy_margin.sim import Simulator, get_engine
from energy_margin.sim.base import CompiledModel, IncompatibleModelsError, ObjectContacts
from energy_margin.tasks import Task, with_contacts
from energy_margin.tasks.protocols import PhysicsReadout
from energy_margin.world.state import FrameState

__all__ = [
    "ANALYSIS_MODELS",
    "CONVERGE_RULES",
    "DEVICES",
    "FRAMES_TOGETHER",
    "AnalyzerConfig",
    "FrameAnalyzer",
    "FrameScores",
    "ScoresConverged",
    "analyze_frame",
    "analyze_frames",
    "field_membership",
    "frame_seeds",
    "score_field",
]


def analyze_frame(
    task: Task,
    frame: FrameState,
    *,
    friction: float,
    drive: np.ndarray,
    seed: int,
    config: AnalyzerConfig | None = None,
    start_time: float = 0.0,
    simulator: Simulator | None = None,
    stop: Callable[[CostField], bool] | None = None,
    check_every: int | None = None,
    deadline: float | None = None,
) -> tuple[FrameScores, CostField]:
    """Grow a tree (``config.method``, EST by default) from ``frame`` and score it.

    Args:
        task: the task.
        frame: the state z_init.
        friction: Coulomb coefficient of the frame's trajectory.
        drive: drive parameters of the trajectory, shape (n_drive,).
        seed: the frame's seed.
        config: analysis settings (defaults when ``None``).
        start_time: time of the frame within its roll-out, s.
        simulator: a simulator of the frame's scene under ``config.contacts`` (the scene of
            ``with_contacts(task, config.contacts)``), to reuse one across frames.
        stop: a further early-stopping rule of the caller's, called with the cost field so far every
            ``check_every`` expansions; growth ends when it or the convergence rule of
            ``config.converge`` says so (the budget stays the upper bound). A wall-clock budget is
            ``deadline``, which reads no field.
        check_every: expansions between two calls of ``stop``, >= 1 (``config.converge_every``
            when ``None``); the convergence rule keeps its own period.
        deadline: a ``time.perf_counter()`` reading, s: growth ends at the first round that ends
            after it (a wall-clock budget; :attr:`TreeBudget.deadline`), or ``None``.

    Returns:
        The scores and the energy-cost field.

    """
    config = config if config is not None else AnalyzerConfig()
    recorded_task, task = task, with_contacts(task, config.contacts)
    simulator = _frame_simulator(recorded_task, task, frame, friction, drive, config, simulator)
    lam = config.likelihood_lambda if config.likelihood_lambda is not None else task.config.likelihood_lambda
    started = time.perf_counter()
    every = config.converge_every if check_every is None or stop is None else check_every
    stop = _stopping_rule(task, frame, lam, config, stop)
    field = grow_tree(
        simulator,
        task,
        frame,
        np.asarray(drive, dtype=float),
        np.random.default_rng(seed),
        budget=config.budget if deadline is None else dataclasses.replace(config.budget, deadline=deadline),
        cost_model=make_cost_model(config.cost),
        features=make_features(config.projection, simulator.scene),
        n_projections=config.n_projections,
        cell_size=config.cell_size,
        start_time=start_time,
        method=config.method,
        batch=config.batch,
        threads=config.threads,
        rollout_length=config.rollout_length,
        rrt_extent=config.rrt_extent,
        wrench_scale=config.wrench_scale,
        duration_scale=config.duration_scale,
        stop=stop,
        check_every=every,
    )
    tree_capture, success = score_field(task, frame, field, lam)
    capture = gate_capture(tree_capture, task.is_captured(frame), config.capture_gate)
    if config.continuation:
        success = continued_success(simulator, task, frame, field, drive, lam=lam, samples=config.continuation,
            seed=seed, start_time=start_time, horizon=config.continuation_horizon, batched_states=config.batch > 1,
            threads=config.threads).success_score  # fmt: skip
    runtime = time.perf_counter() - started
    scores = FrameScores(capture, success, field.nodes, field.expansions, runtime, field.physics_s, field.rejected,
        field.diverged, tree_capture)  # fmt: skip
    return scores, field


def analyze_frames(
    task: Task,
    frames: Sequence[FrameState],
    *,
    frictions: Sequence[float],
    drives: Sequence[np.ndarray],
    seeds: Sequence[int],
    start_times: Sequence[float],
    config: AnalyzerConfig,
    simulators: Sequence[Simulator] | None = None,
    propagating: Simulator | None = None,
) -> list[tuple[FrameScores, CostField]]:
    """Score frames of one scene with their trees grown in lockstep, each round one batched call.

    Every frame gets the scores :func:`analyze_frame` gives it alone with the same seed and
    ``config`` (its tree is the same, ``config.batch`` expansions a round); only where the
    propagations run changes: on an engine with :attr:`~energy_margin.sim.Engine.grows_together`,
    the worlds of every tree step together on the device. The frames may come from several
    roll-outs (each its friction and drive).

    Args:
        task: the task.
        frames: the frames.
        frictions: each frame's Coulomb coefficient (its roll-out's).
        drives: each frame's drive parameters (its roll-out's), shape (n_drive,).
        seeds: each frame's seed.
        start_times: each frame's time within its roll-out, s.
        config: analysis settings, ``batch`` > 1; a ``continuation`` runs every frame's in one
            batched call too (:func:`continued_successes_together`).
        simulators: each frame's simulator (as :func:`analyze_frame`'s; frames of one roll-out
            may share one); built when ``None``.
        propagating: the simulator of the scene whose batched propagator runs every call (the
            first frame's when ``None``): one device copy of the model serves every group.

    Returns:
        Each frame's scores and cost field; ``runtime_s`` is the group's wall time over its frames.

    """
    if config.batch < 2:
        raise InvalidParameterError("config", "needs batch > 1 to grow frames together")
    recorded_task, task = task, with_contacts(task, config.contacts)
    chosen = _frame_simulators(recorded_task, task, frames, frictions, drives, config, simulators)
    lam = config.likelihood_lambda if config.likelihood_lambda is not None else task.config.likelihood_lambda
    started = time.perf_counter()
    fields = grow_trees_together(
        chosen,
        task,
        list(frames),
        [np.asarray(drive, dtype=float) for drive in drives],
        [np.random.default_rng(seed) for seed in seeds],
        budget=config.budget,
        cost_model=make_cost_model(config.cost),
        start_times=list(start_times),
        batch=config.batch,
        features=make_features(config.projection, chosen[0].scene),
        n_projections=config.n_projections,
        cell_size=config.cell_size,
        method=config.method,
        rollout_length=config.rollout_length,
        rrt_extent=config.rrt_extent,
        stops=[_stopping_rule(task, frame, lam, config, None) for frame in frames],
        check_every=config.converge_every,
        wrench_scale=config.wrench_scale,
        duration_scale=config.duration_scale,
        propagating=propagating,
    )
    continued: list[float | None] = [None] * len(frames)
    if config.continuation:
        lead = propagating if propagating is not None else chosen[0]
        found = continued_successes_together(
            lead,  # type: ignore[arg-type]
            task, frames, fields, list(drives), [simulator.model for simulator in chosen],  # type: ignore[attr-defined]
            lam=lam, samples=config.continuation, seeds=seeds, start_times=start_times,
            horizon=config.continuation_horizon,
        )  # fmt: skip
        continued = [one.success_score for one in found]
    runtime = (time.perf_counter() - started) / len(frames)
    return _scored_together(task, frames, fields, continued, lam, runtime, capture_gate=config.capture_gate)


def _scored_together(
    task: Task,
    frames: Sequence[FrameState],
    fields: list[CostField],
    continued: list[float | None],
    lam: float,
    runtime: float,
    *,
    capture_gate: str,
) -> list[tuple[FrameScores, CostField]]:
    """Each frame's scores from its tree (its success score from continuations where given) and field."""
    results = []
    for frame, field, continued_score in zip(frames, fields, continued, strict=True):
        tree_capture, success = score_field(task, frame, field, lam)
        capture = gate_capture(tree_capture, task.is_captured(frame), capture_gate)
        success = success if continued_score is None else continued_score
        scores = FrameScores(capture, success, field.nodes, field.expansions, runtime, field.physics_s, field.rejected,
            field.diverged, tree_capture)  # fmt: skip
        results.append((scores, field))
    return results


def _frame_simulators(
    recorded_task: Task,
    task: Task,
    frames: Sequence[FrameState],
    frictions: Sequence[float],
    drives: Sequence[np.ndarray],
    config: AnalyzerConfig,
    simulators: Sequence[Simulator] | None,
) -> list[Simulator]:
    """Each frame's simulator (:func:`_frame_simulator`); one shared by a roll-out's frames is checked once."""
    given: Sequence[Simulator | None] = simulators if simulators is not None else [None] * len(frames)
    chosen: list[Simulator] = []
    checked: set[int] = set()  # a simulator shared by a roll-out's frames is checked (and pruned) once
    for frame, friction, drive, simulator in zip(frames, frictions, drives, given, strict=True):
        if simulator is None or id(simulator) not in checked:
            simulator = _frame_simulator(recorded_task, task, frame, friction, drive, config, simulator)
            checked.add(id(simulator))
        chosen.append(simulator)
    return chosen


def _frame_simulator(
    recorded_task: PhysicsReadout,
    task: Task,
    frame: FrameState,
    friction: float,
    drive: np.ndarray,
    config: AnalyzerConfig,
    simulator: Simulator | None,
) -> Simulator:
    """The given simulator, checked to be of ``task``'s scene (its contacts), or a new one."""
    if simulator is None:
        simulator = task.make_simulator(frame.n_objects, friction, drive, config.engine, device=config.device)
    elif task is not recorded_task and getattr(simulator, "scene", None) != task.build_scene(
        frame.n_objects, friction, drive
    ):
        # A simulator of the recorded scene would silently analyse the other contact model.
        raise InvalidParameterError("simulator", f"is not a simulator of the scene of contacts {config.contacts!r}")
    if isinstance(simulator, ObjectContacts):
        if config.analysis_model == "pruned":
            simulator.keep_object_contacts()
        elif getattr(simulator, "pruned_contacts", None) is not None:
            raise InvalidParameterError("simulator", "simulates the pruned analysis model, not the 'full' one")
    return simulator


def _stopping_rule(
    task: Task, frame: FrameState, lam: float, config: AnalyzerConfig, stop: Callable[[CostField], bool] | None
) -> Callable[[CostField], bool] | None:
    """``stop``, or-ed with the convergence rule of ``config.converge`` when it is on (lambda in 1/J)."""
    if config.converge is not None:
        converged = ScoresConverged(
            task,
            frame,
            lam,
            tolerance=config.converge,
            window=config.converge_window,
            rule=config.converge_rule,
            budget=config.budget,
        )
        stop = converged if stop is None else EitherStop(stop, converged, config.converge_every)
    return stop


_SIMULATOR_CACHE = 4
#: Frames an engine that grows trees together scores in one lockstep growth: 100 frames of 32
#: expansions a round are 3,200 worlds a call; the journal is written after each group.
FRAMES_TOGETHER = 100


class FrameAnalyzer:
    """Scores frames of one dataset, reusing one simulator per distinct (friction, drive) pair."""

    def __init__(self, dataset: Dataset, config: AnalyzerConfig, seed: int) -> None:
        self.dataset = dataset
        self.task = with_contacts(dataset.task, config.contacts)
        self.config = config
        total = dataset.n_trajectories * dataset.n_frames
        self.seeds = frame_seeds(seed, total)
        self._simulators: dict[tuple[float, bytes], Simulator] = {}
        self._lead: Simulator | None = None

    def _simulator(self, friction: float, drive: np.ndarray) -> Simulator:
        # The drive may change the model (e.g. a servo stiffness), so it is part of the key.
        key = (friction, np.asarray(drive, dtype=float).tobytes())
        simulator = self._simulators.pop(key, None)
        if simulator is None:
            # Frames arrive trajectory by trajectory: a few recent simulators suffice (memory stays bounded).
            while len(self._simulators) >= _SIMULATOR_CACHE:
                self._simulators.pop(next(iter(self._simulators)))
            simulator = self.task.make_simulator(
                self.dataset.n_objects, friction, drive, self.config.engine, device=self.config.device
            )
        self._simulators[key] = simulator
        return simulator

    def __call__(self, index: int) -> dict[str, Any]:
        """The scores row of frame ``index`` (trajectory-major)."""
        return self.analyse(index)[0]

    def rows(self, indices: Sequence[int]) -> Iterator[dict[str, Any]]:
        """The scores rows of frames ``indices``, in order.

        On an engine that grows trees together, up to :data:`FRAMES_TOGETHER` consecutive frames
        (of one or more roll-outs) are scored in one lockstep growth (:func:`analyze_frames`);
        the rows are the same as one at a time.
        """
        if not self._together:
            for index in indices:
                yield self(index)
            return
        for at in range(0, len(indices), FRAMES_TOGETHER):
            yield from self._rows_together(list(indices[at : at + FRAMES_TOGETHER]))

    @property
    def _together(self) -> bool:
        config = self.config
        return get_engine(config.engine).grows_together and config.batch > 1

    def _rows_together(self, indices: list[int]) -> list[dict[str, Any]]:
        dataset = self.dataset
        places = [divmod(index, dataset.n_frames) for index in indices]
        frictions = [float(dataset.arrays["friction"][trajectory]) for trajectory, _ in places]
        drives = [dataset.arrays["drive"][trajectory] for trajectory, _ in places]
        simulators = [self._simulator(friction, drive) for friction, drive in zip(frictions, drives, strict=True)]
        if isinstance(simulators[0], CompiledModel) and simulators[0].model.nmocap:
            # A command without mocap poses holds the root's: one root per batched call.
            return [self(index) for index in indices]
        if self._lead is None:
            self._lead = simulators[0]
        # Every group's calls run on one simulator's device copy, built once.
        lead = self._lead
        try:
            results = self._grown_together(indices, places, frictions, drives, simulators, lead)
        except IncompatibleModelsError:
            # Roll-outs whose models differ in more than the engine batches per world: one
            # roll-out per group, on its own simulator.
            rows = []
            for trajectory in dict.fromkeys(trajectory for trajectory, _ in places):
                mine = [at for at, (owner, _) in enumerate(places) if owner == trajectory]
                group = [indices[at] for at in mine]
                results = self._grown_together(group, [places[at] for at in mine], [frictions[at] for at in mine],
                                               [drives[at] for at in mine], [simulators[at] for at in mine],
                                               simulators[mine[0]])  # fmt: skip
                rows += [self._row(index, scores) for index, (scores, _) in zip(group, results, strict=True)]
            return rows
        return [self._row(index, scores) for index, (scores, _) in zip(indices, results, strict=True)]

    def _grown_together(
        self,
        indices: list[int],
        places: list[tuple[int, int]],
        frictions: list[float],
        drives: list[np.ndarray],
        simulators: list[Simulator],
        lead: Simulator,
    ) -> list[tuple[FrameScores, CostField]]:
        dataset = self.dataset
        return analyze_frames(
            self.task,
            [dataset.frame(trajectory, frame) for trajectory, frame in places],
            frictions=frictions,
            drives=drives,
            seeds=[self.seeds[index] for index in indices],
            start_times=[float(dataset.arrays["frame_time"][trajectory, frame]) for trajectory, frame in places],
            config=self.config,
            simulators=simulators,
            propagating=lead,
        )

    def analyse(self, index: int) -> tuple[dict[str, Any], CostField]:
        """The scores row of frame ``index`` (trajectory-major) and the cost field it was scored on."""
        dataset = self.dataset
        trajectory, frame_index = divmod(index, dataset.n_frames)
        friction = float(dataset.arrays["friction"][trajectory])
        drive = dataset.arrays["drive"][trajectory]
        scores, field = analyze_frame(
            self.task,
            dataset.frame(trajectory, frame_index),
            friction=friction,
            drive=drive,
            seed=self.seeds[index],
            config=self.config,
            start_time=float(dataset.arrays["frame_time"][trajectory, frame_index]),
            simulator=self._simulator(friction, drive),
        )
        return self._row(index, scores), field

    def _row(self, index: int, scores: FrameScores) -> dict[str, Any]:
        trajectory, frame_index = divmod(index, self.dataset.n_frames)
        return {
            "trajectory": trajectory,
            "frame": frame_index,
            "capture_score": scores.capture_score,
            "success_score": scores.success_score,
            "nodes": scores.nodes,
            "expansions": scores.expansions,
            "runtime_s": scores.runtime_s,
            "physics_s": scores.physics_s,
            "seed": self.seeds[index],
            "rejected": scores.rejected,
            "diverged": scores.diverged,
            "tree_capture_score": scores.tree_capture_score,
        }
