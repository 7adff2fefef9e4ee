"""Energy margins of one frame (Algorithm 1): grow a tree from the state and score it.

``analyze_frame`` scores one state; :class:`FrameAnalyzer` scores the frames of one dataset by
index, reusing simulators, with per-frame seeds from :func:`frame_seeds` so that the scores do not
depend on the number of workers or on the order in which frames finish.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from energy_margin._renamed import renamed_fields
from energy_margin.analysis.continuation import continued_success
from energy_margin.analysis.convergence import (
    CONVERGE_RULES,
    EitherStop,
    ScoresConverged,
    field_membership,
    frame_seeds,
    score_field,
)
from energy_margin.data.dataset import Dataset
from energy_margin.errors import (
    Constraint,
    InvalidParameterError,
    check_fields,
    constrained,
)
from energy_margin.planning import CostField, TreeBudget, grow_tree
from energy_margin.planning.costs import COST_MODELS, make_cost_model
from energy_margin.planning.density import PROJECTIONS, make_features
from energy_margin.planning.methods import METHODS
from energy_margin.sim import ENGINES, Simulator
from energy_margin.sim.base import ObjectContacts
from energy_margin.tasks import Task, with_contacts
from energy_margin.tasks.base import CONTACT_MODELS
from energy_margin.tasks.protocols import PhysicsReadout
from energy_margin.world.state import FrameState

__all__ = [
    "ANALYSIS_MODELS",
    "CONVERGE_RULES",
    "AnalyzerConfig",
    "FrameAnalyzer",
    "FrameScores",
    "ScoresConverged",
    "analyze_frame",
    "field_membership",
    "frame_seeds",
    "score_field",
]

#: Models an analysis simulates (:attr:`AnalyzerConfig.analysis_model`).
ANALYSIS_MODELS = ("pruned", "full")


@renamed_fields(iterations="expansions")
@dataclass(frozen=True)
class AnalyzerConfig:
    """Settings of an energy-margin analysis.

    Attributes:
        expansions: tree expansions per frame (accepted or rejected); ``None`` for a node budget only.
        nodes: accepted tree nodes (children of the root) per frame; ``None`` for no node budget.
        cost: incremental cost model, ``"wrench"`` (perturbation work) or ``"energy"`` (|dE - W_fri|).
        likelihood_lambda: softmax inverse temperature lambda, 1/J; ``None`` uses the task's value.
        n_projections: random projections of the EST density estimate.
        cell_size: density grid cell width, m.
        engine: physics engine.
        method: tree method, ``"est"`` (the paper), ``"montecarlo"`` (independent roll-outs) or
            ``"rrt"`` (nearest node to a random target, one random control); see
            :mod:`energy_margin.planning.methods`.
        batch: expansions propagated together per round through ``mujoco.rollout`` (1: one at a
            time, the reference behaviour; > 1 needs the ``"wrench"`` cost).
        threads: ``mujoco.rollout`` threads when ``batch`` > 1.
        rollout_length: propagations per Monte Carlo roll-out.
        rrt_extent: half width of the RRT target box, m.
        projection: EST density features, ``"objects"`` (every object's centre relative to the
            root) or ``"ellipsoid"`` (centre and shape matrix of the ellipsoid of the centres).
        converge: adaptive budget: a score tolerance in (0, 1); the tree stops once the rule of
            ``converge_rule`` says neither score will move by more than it (checked every
            ``converge_every`` expansions); the expansion/node budget stays the upper bound.
            ``None``: always spend the whole budget.
        converge_rule: ``"projected"``: stop once neither score, moving on at its rate over the
            last ``converge_window`` expansions, would move by more than ``converge`` by the end
            of the budget; ``"window"``: once neither moved by more than ``converge`` over the
            last ``converge_window`` expansions. Scores drift slowly down as a tree grows into
            costlier states, and the window rule stops a slow drift early (biased high); the
            projected rule is the one whose AP holds (docs/results/performance.md).
        converge_window: expansions the convergence rule looks back over.
        converge_every: expansions between two convergence checks.
        contacts: contact model of the analysis: ``"recorded"`` (the dataset's task settings) or
            ``"fast"`` (the task's fast contact model, :attr:`TaskConfig.fast_contacts`: the same
            contacts from cheaper pairs; pushing: footprint ground contacts and sphere stand-ins).
        analysis_model: ``"pruned"``: simulate the analysis model, the frame's model less the
            contact pairs that cannot move an object (robot self-collision; robot-world pairs
            when the robot is held still), exact while no dropped pair touches
            (:mod:`energy_margin.sim.analysis_model`; MuJoCo); ``"full"``: the model as it is.
        wrench_scale: factor on the task's perturbation wrench bounds (1: the task's own).
        duration_scale: factor on the task's longest perturbation propagation (1: the task's own).
        continuation: nodes drawn by likelihood whose unperturbed scripted motion scores success
            (MuJoCo; :mod:`energy_margin.analysis.continuation`); 0: the tree's own success score.
        continuation_horizon: longest continuation, s past its node; ``None``: to the task's duration.

    """

    expansions: int | None = constrained(300, Constraint("int", minimum=0, optional=True))
    nodes: int | None = constrained(None, Constraint("int", minimum=0, optional=True))
    cost: str = constrained("wrench", Constraint("choice", choices=tuple(COST_MODELS)))
    likelihood_lambda: float | None = constrained(None, Constraint("float", minimum=0.0, optional=True))
    n_projections: int = constrained(8, Constraint("int", minimum=1))
    cell_size: float = constrained(0.01, Constraint("float", minimum=0.0, exclusive=True))
    engine: str = constrained("mujoco", Constraint("choice", choices=tuple(ENGINES)))
    method: str = constrained("est", Constraint("choice", choices=tuple(METHODS)))
    batch: int = constrained(1, Constraint("int", minimum=1))
    threads: int = constrained(1, Constraint("int", minimum=1))
    rollout_length: int = constrained(10, Constraint("int", minimum=1))
    rrt_extent: float = constrained(0.1, Constraint("float", minimum=0.0, exclusive=True))
    projection: str = constrained("objects", Constraint("choice", choices=tuple(PROJECTIONS)))
    converge: float | None = constrained(
        None, Constraint("float", minimum=0.0, maximum=1.0, exclusive=True, optional=True)
    )
    converge_rule: str = constrained("projected", Constraint("choice", choices=CONVERGE_RULES))
    converge_window: int = constrained(50, Constraint("int", minimum=1))
    converge_every: int = constrained(25, Constraint("int", minimum=1))
    contacts: str = constrained("recorded", Constraint("choice", choices=tuple(CONTACT_MODELS)))
    analysis_model: str = constrained("pruned", Constraint("choice", choices=ANALYSIS_MODELS))
    wrench_scale: float = constrained(1.0, Constraint("float", minimum=0.0, exclusive=True))
    duration_scale: float = constrained(1.0, Constraint("float", minimum=0.0, exclusive=True))
    continuation: int = constrained(0, Constraint("int", minimum=0))
    continuation_horizon: float | None = constrained(
        None, Constraint("float", minimum=0.0, exclusive=True, optional=True)
    )

    def __post_init__(self) -> None:
        # Each field's constraint is declared once, beside its default (the command line takes both).
        check_fields(self)
        if self.expansions is None and self.nodes is None:
            raise InvalidParameterError("expansions", "and nodes cannot both be None")
        if self.batch > 1 and make_cost_model(self.cost).needs_friction_work:
            raise InvalidParameterError(
                "cost", f"must be 'wrench' with batch > 1, which does not integrate friction work, got {self.cost!r}"
            )
        if self.contacts == "fast" and self.engine != "mujoco":
            raise InvalidParameterError(
                "contacts", f"'fast' is a MuJoCo contact model, not available with engine {self.engine!r}"
            )
        if self.continuation and self.engine != "mujoco":
            raise InvalidParameterError("continuation", f"needs the 'mujoco' engine, not {self.engine!r}")

    @property
    def budget(self) -> TreeBudget:
        """The tree budget."""
        return TreeBudget(expansions=self.expansions, nodes=self.nodes)

    def to_dict(self) -> dict[str, Any]:
        """JSON-compatible dictionary of every field."""
        return dataclasses.asdict(self)


@renamed_fields(iterations="expansions")
@dataclass(frozen=True)
class FrameScores:
    """Scores of one frame.

    Attributes:
        capture_score: likelihood mass of captured states, in [0, 1].
        success_score: likelihood mass of successful states, in [0, 1].
        nodes: tree nodes including the root.
        expansions: expansions performed.
        runtime_s: wall time of tree growth and scoring, s.
        physics_s: part of it spent in the simulator, s.
        rejected: reached states the tree rejected for leaving the task's state box.
        diverged: reached states the tree rejected for a non-finite number (a blow-up).

    """

    capture_score: float
    success_score: float
    nodes: int
    expansions: int
    runtime_s: float
    physics_s: float
    rejected: int = 0
    diverged: int = 0


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
        stop: a further early-stopping rule (e.g. a wall-clock deadline), called with the cost
            field so far every ``check_every`` expansions; growth ends when it or the
            convergence rule of ``config.converge`` says so (the budget stays the upper bound).
        check_every: expansions between two calls of ``stop``, >= 1 (``config.converge_every``
            when ``None``); the convergence rule keeps its own period.

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
        budget=config.budget,
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
    capture, success = score_field(task, frame, field, lam)
    if config.continuation:
        success = continued_success(simulator, task, frame, field, drive, lam=lam, samples=config.continuation,
            seed=seed, start_time=start_time, horizon=config.continuation_horizon, batched_states=config.batch > 1,
            threads=config.threads).success_score  # fmt: skip
    runtime = time.perf_counter() - started
    scores = FrameScores(
        capture, success, field.nodes, field.expansions, runtime, field.physics_s, field.rejected, field.diverged
    )
    return scores, field


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
        simulator = task.make_simulator(frame.n_objects, friction, drive, config.engine)
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


class FrameAnalyzer:
    """Scores frames of one dataset, reusing one simulator per distinct (friction, drive) pair."""

    def __init__(self, dataset: Dataset, config: AnalyzerConfig, seed: int) -> None:
        self.dataset = dataset
        self.task = with_contacts(dataset.task, config.contacts)
        self.config = config
        total = dataset.n_trajectories * dataset.n_frames
        self.seeds = frame_seeds(seed, total)
        self._simulators: dict[tuple[float, bytes], Simulator] = {}

    def _simulator(self, friction: float, drive: np.ndarray) -> Simulator:
        # The drive may change the model (e.g. a servo stiffness), so it is part of the key.
        key = (friction, np.asarray(drive, dtype=float).tobytes())
        simulator = self._simulators.pop(key, None)
        if simulator is None:
            # Frames arrive trajectory by trajectory: a few recent simulators suffice (memory stays bounded).
            while len(self._simulators) >= _SIMULATOR_CACHE:
                self._simulators.pop(next(iter(self._simulators)))
            simulator = self.task.make_simulator(self.dataset.n_objects, friction, drive, self.config.engine)
        self._simulators[key] = simulator
        return simulator

    def __call__(self, index: int) -> dict[str, Any]:
        """The scores row of frame ``index`` (trajectory-major)."""
        return self.analyse(index)[0]

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
        }, field
