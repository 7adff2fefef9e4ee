"""The settings of an analysis (:class:`AnalyzerConfig`) and the scores of one frame (:class:`FrameScores`)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

from energy_margin._renamed import renamed_fields
from energy_margin.analysis.convergence import CONVERGE_RULES
from energy_margin.analysis.scores import CAPTURE_GATES
from energy_margin.errors import Constraint, InvalidParameterError, check_fields, constrained
from energy_margin.planning import TreeBudget
from energy_margin.planning.costs import COST_MODELS, make_cost_model
from energy_margin.planning.density import PROJECTIONS
from energy_margin.planning.methods import METHODS
from energy_margin.sim import ENGINE_REGISTRY, ENGINES, get_engine
from energy_margin.tasks.base import CONTACT_MODELS

__all__ = ["ANALYSIS_MODELS", "DEVICES", "AnalyzerConfig", "FrameScores"]

#: Devices of an engine that has them (:attr:`AnalyzerConfig.device`).
DEVICES = ("cuda", "cpu")

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
        engine: physics engine (:data:`energy_margin.sim.ENGINE_REGISTRY`); ``"mujoco-warp"`` runs
            every round of expansions on MuJoCo Warp and grows a roll-out's trees together (needs
            ``batch`` > 1).
        device: where an engine with devices runs, ``"cuda"`` or ``"cpu"``; ``None``: its first
            (``"cuda"`` for ``"mujoco-warp"``). Engines without devices take ``None`` only.
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
            projected rule is the one whose AP holds (docs/results/performance.md);
            ``"projected-reached"``: the projected rule once the success score has left 0 (a tree
            that has not reached the success region does not stop; docs/results/budget.md).
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
            (an engine that :attr:`~energy_margin.sim.Engine.continues`: MuJoCo's;
            :mod:`energy_margin.analysis.continuation`); 0: the tree's own success score;
            ``None``: ``analyze``'s default (:mod:`energy_margin.analysis.continuation_rule`: 16
            on an engine that continues, else 0); a frame analysed alone takes ``None`` as 0.
        continuation_horizon: longest continuation, s past its node; ``None``: to the task's duration.
        capture_gate: ``"current"``: a frame whose own objects are not all in its capture region
            scores capture 0 (they are lost already; the label at k-hat 0 says so); ``"none"``:
            the tree's likelihood mass alone, the paper's capture score (``reproduce``).

    """

    expansions: int | None = constrained(300, Constraint("int", minimum=0, optional=True))
    nodes: int | None = constrained(None, Constraint("int", minimum=0, optional=True))
    cost: str = constrained("wrench", Constraint("choice", choices=tuple(COST_MODELS)))
    likelihood_lambda: float | None = constrained(None, Constraint("float", minimum=0.0, optional=True))
    n_projections: int = constrained(8, Constraint("int", minimum=1))
    cell_size: float = constrained(0.01, Constraint("float", minimum=0.0, exclusive=True))
    engine: str = constrained("mujoco", Constraint("choice", choices=tuple(ENGINES)))
    device: str | None = constrained(None, Constraint("choice", choices=DEVICES, optional=True))
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
    continuation: int | None = constrained(None, Constraint("int", minimum=0, optional=True))
    continuation_horizon: float | None = constrained(
        None, Constraint("float", minimum=0.0, exclusive=True, optional=True)
    )
    capture_gate: str = constrained("current", Constraint("choice", choices=CAPTURE_GATES))

    def __post_init__(self) -> None:
        # Each field's constraint is declared once, beside its default (the command line takes both).
        check_fields(self)
        if self.expansions is None and self.nodes is None:
            raise InvalidParameterError("expansions", "and nodes cannot both be None")
        if self.batch > 1 and make_cost_model(self.cost).needs_friction_work:
            raise InvalidParameterError(
                "cost", f"must be 'wrench' with batch > 1, which does not integrate friction work, got {self.cost!r}"
            )
        if self.contacts not in get_engine(self.engine).contact_models:
            raise InvalidParameterError(
                "contacts", f"{self.contacts!r} is a MuJoCo contact model, not available with engine {self.engine!r}"
            )
        if self.device is not None and self.device not in get_engine(self.engine).devices:
            raise InvalidParameterError(
                "device", f"must be None with engine {self.engine!r}, which runs on the CPU: got {self.device!r}"
            )
        if get_engine(self.engine).grows_together and self.batch < 2:
            raise InvalidParameterError(
                "batch", f"must be > 1 with engine {self.engine!r}: each round of expansions is one batched call"
            )
        if self.continuation and not get_engine(self.engine).continues:
            able = " or ".join(repr(name) for name, engine in ENGINE_REGISTRY.items() if engine.continues)
            raise InvalidParameterError("continuation", f"needs the {able} engine, not {self.engine!r}")

    def fixed_continuation(self) -> AnalyzerConfig:
        """These settings with ``continuation=None`` taken as 0, for protocols that compare analyses.

        A budget sweep, a design search or the paper's reproduction compares scores across runs,
        so every run scores success one way, stated: the tree's own success score unless a K is given.
        """
        return self if self.continuation is not None else dataclasses.replace(self, continuation=0)

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
        tree_capture_score: the tree's own capture score (eq. 2) before ``capture_gate``: equal
            to ``capture_score`` unless the gate scored the frame 0; what a capture alarm watches
            (a successful roll-out whose objects leave their region for a moment keeps it). NaN
            where unknown (scores no tree of this package grew).

    """

    capture_score: float
    success_score: float
    nodes: int
    expansions: int
    runtime_s: float
    physics_s: float
    rejected: int = 0
    diverged: int = 0
    tree_capture_score: float = math.nan
