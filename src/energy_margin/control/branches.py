"""Can a controller change an episode's outcome, and does its cost know which change helps?

A controller can only gain over its script where (1) some of the command sequences it samples
lead to another outcome than the script's and (2) its cost ranks the sequences that succeed above
those that fail. :func:`branch_study` measures both on the plant itself. For every episode it runs
the command space's nominal commands (the controller's plan with no deviation) on the disturbed
plant; at each decision time it samples the controller's K command sequences from the state the
plant is in, executes each on a copy of the plant (the same friction and pushes, sequence k for
the H periods of the horizon, then the nominal commands to the end) and records whether the
episode then succeeds. Each sequence is also scored as the controller scores it, from the
nominal model's prediction of the observed state: the ``task`` cost, the margin (capture +
success score of the predicted end state) and, with a model, the learned margin.

A *split* state is one whose K branches do not all end alike: only there does the choice of a
sequence matter. The *concordance* of a score is the probability that, at a split state, a
branch that succeeds scores better than one that fails (ties count half): 0.5 is a coin, 1 a
cost that always picks a winning sequence.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, replace
from functools import partial
from typing import Any

import numpy as np

from energy_margin.control.commands import CommandSpace, command_space
from energy_margin.control.costs import CostContext, CostWeights, MarginPredictor, margin_scores, task_cost
from energy_margin.control.disturbances import Disturbance, Push, push_wrenches
from energy_margin.control.episodes import apply_inputs, draw_episode, episode_seeds, observed_frame
from energy_margin.control.mppi import Controller, ControllerConfig
from energy_margin.errors import EnergyMarginError, InvalidParameterError, check_int, check_seed
from energy_margin.sim import Simulator
from energy_margin.tasks import Task, Trajectory
from energy_margin.tasks.protocols import TaskRegions
from energy_margin.world.state import FrameState

__all__ = [
    "SCORES",
    "BranchState",
    "BranchStudy",
    "branch_episode",
    "branch_study",
    "concordance",
]

#: The scores a study can rank branches by; each is "higher is better". ``oracle_state`` is the
#: ``task`` score predicted from the true state instead of the observed one, ``oracle_friction``
#: from the true state with the plant's friction: what a controller would see with perfect
#: perception, and with perfect perception and friction (only the future pushes unknown).
SCORES = ("task", "margin", "learned", "oracle_state", "oracle_friction")


@dataclass(frozen=True)
class BranchState:
    """The K branches of one decision state.

    Attributes:
        episode: index of the episode.
        time: decision time, s.
        nominal_success: whether the episode succeeds with the nominal commands throughout.
        outcomes: whether each branch's episode succeeds, shape (K,); branch 0 is the nominal one.
        scores: each score's value of every branch, shape (K,), higher is better (``task`` is the
            negated task cost).

    """

    episode: int
    time: float
    nominal_success: bool
    outcomes: np.ndarray
    scores: dict[str, np.ndarray]

    @property
    def split(self) -> bool:
        """Whether some branches succeed and others fail."""
        return bool(self.outcomes.any() and not self.outcomes.all())


def concordance(states: Sequence[BranchState], score: str) -> tuple[float, int]:
    """P(a succeeding branch scores above a failing one) over the split states' pairs, and the pair count.

    Ties count half. ``nan`` with 0 pairs when no state splits.
    """
    wins, pairs = 0.0, 0
    for state in states:
        if not state.split:
            continue
        values = state.scores[score]
        good, bad = values[state.outcomes], values[~state.outcomes]
        difference = good[:, None] - bad[None, :]
        wins += float(np.sum(difference > 0) + 0.5 * np.sum(difference == 0))
        pairs += difference.size
    return (wins / pairs if pairs else float("nan")), pairs


@dataclass(frozen=True)
class BranchStudy:
    """Every decision state of a study, with its settings.

    Attributes:
        settings: what the study ran (task, objects, disturbance, seed, times, controller).
        states: the decision states, episode by episode.
        nominal_successes: whether each episode succeeds with the nominal commands, shape (E,).

    """

    settings: dict[str, Any]
    states: list[BranchState] = field(default_factory=list)
    nominal_successes: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))

    def summary(self) -> dict[str, Any]:
        """Rates of splitting and rescue, and each score's concordance (overall and per decision time)."""
        episodes = len(self.nominal_successes)
        by_episode: dict[int, list[BranchState]] = {}
        for state in self.states:
            by_episode.setdefault(state.episode, []).append(state)
        # An episode is "reachable" when some branch at some decision state succeeds.
        reachable = [any(state.outcomes.any() for state in by_episode.get(e, [])) for e in range(episodes)]
        failing = [e for e in range(episodes) if not self.nominal_successes[e]]
        scores = [name for name in SCORES if self.states and name in self.states[0].scores]
        times = sorted({state.time for state in self.states})
        per_time = []
        for time in times:
            at_time = [state for state in self.states if state.time == time]
            row: dict[str, Any] = {
                "time": time,
                "states": len(at_time),
                "split": sum(state.split for state in at_time),
                "branch_success": float(np.mean([state.outcomes[1:].mean() for state in at_time])),
                "rescued": sum(1 for state in at_time if not state.nominal_success and state.outcomes.any()),
                "spoiled": sum(1 for state in at_time if state.nominal_success and not state.outcomes.all()),
            }
            for name in scores:
                row[f"concordance_{name}"], row[f"pairs_{name}"] = concordance(at_time, name)
            per_time.append(row)
        result: dict[str, Any] = {
            "episodes": episodes,
            "nominal_success_rate": float(np.mean(self.nominal_successes)) if episodes else None,
            "states": len(self.states),
            "split_states": sum(state.split for state in self.states),
            "reachable_success_rate": float(np.mean(reachable)) if episodes else None,
            "rescuable_failures": sum(1 for e in failing if reachable[e]),
            "failures": len(failing),
            "per_time": per_time,
        }
        for name in scores:
            result[f"concordance_{name}"], result[f"pairs_{name}"] = concordance(self.states, name)
        return result


def _play(
    plant: Simulator,
    space: CommandSpace,
    commands: np.ndarray,
    *,
    held: np.ndarray | None,
    start_step: int,
    end_step: int,
    period_steps: int,
    pushes: list[Push],
    n_objects: int,
    on_period: Callable[[int, np.ndarray | None], None] | None = None,
) -> np.ndarray | None:
    """Hold each command (P, m) for one period on ``plant`` from ``start_step``; the servo targets held after.

    ``on_period(step, held)`` is called before each period's first step.
    """
    dt = plant.timestep
    for index, command in enumerate(commands):
        first = start_step + index * period_steps
        if first >= end_step:
            break
        if on_period is not None:
            on_period(first, held)
        inputs = space.inputs(command[None, None], held=held, start_time=first * dt, dt=dt, period_steps=period_steps)
        held = None if inputs.held is None else inputs.held[0]
        for offset in range(min(period_steps, end_step - first)):
            plant.set_object_wrenches(push_wrenches(pushes, (first + offset) * dt, n_objects))
            apply_inputs(plant, inputs, offset)
            plant.step(1)
    return held


def _nominal_commands(space: CommandSpace, trajectory: Trajectory, periods: int, period: float) -> np.ndarray:
    return np.stack([space.nominal(trajectory, index * period) for index in range(periods)])


def branch_episode(
    task: Task,
    index: int,
    seed: np.random.SeedSequence,
    *,
    n_objects: int,
    disturbance: Disturbance,
    decision_times: Sequence[float],
    config: ControllerConfig,
    weights: CostWeights,
    scores: Sequence[str],
    model: MarginPredictor | None = None,
) -> tuple[bool, list[BranchState]]:
    """One episode of a study: whether its nominal run succeeds, and its decision states.

    The episode draws its start, plant and observation noise from the same streams as
    :func:`~energy_margin.control.episodes.run_episode`, so a study's episode i is the control
    run's episode i with the same seed.
    """
    seeds = episode_seeds(seed)
    trajectory, friction, pushes = draw_episode(task, n_objects, disturbance, seeds)
    space = command_space(task, n_objects)
    plant = task.make_simulator(n_objects, friction, trajectory.drive, "mujoco")
    plant.reset(trajectory.initial)
    held = space.initial_targets(trajectory)
    if held is not None:
        plant.set_robot_targets(held)
    dt = plant.timestep
    period_steps = max(1, round(config.period / dt))
    period = period_steps * dt
    periods = -(-task.n_steps // period_steps)
    nominal = _nominal_commands(space, trajectory, periods, period)
    decision_steps = {round(time / period) * period_steps for time in decision_times}
    saved: dict[int, tuple[np.ndarray, np.ndarray | None]] = {}

    def remember(step: int, held_now: np.ndarray | None) -> None:
        if step in decision_steps:
            saved[step] = (plant.get_state(), None if held_now is None else held_now.copy())

    # The plant from a step to the end under the pushes: the nominal run, then each branch.
    play = partial(
        _play, plant, space, end_step=task.n_steps, period_steps=period_steps, pushes=pushes, n_objects=n_objects
    )
    play(nominal, held=held, start_step=0, on_period=remember)
    nominal_success = task.is_successful(plant.frame_state())
    context = _cost_context(task, space, trajectory, weights, config, seeds["cost"], model)
    controller = Controller(task, space, trajectory, task_cost, context, config, np.random.default_rng(seeds["sample"]))
    # A controller whose model has the plant's friction (its sampling generator is never used).
    knowing = Controller(
        task, space, replace(trajectory, friction=friction), task_cost, context, config, np.random.default_rng(0)
    )
    observe_rng = np.random.default_rng(seeds["observe"])
    states = []
    for step in sorted(saved):
        state, held_then = saved[step]
        plant.set_state(state)
        truth = plant.frame_state()
        observed = observed_frame(truth, disturbance, observe_rng)
        time = step * dt
        commands, scripted = controller.sample(time)
        predictions = controller.predict(observed, time, held_then, commands, scripted)
        values = _score_values(
            scores,
            task,
            context,
            predictions,
            (controller, knowing),
            (truth, time, held_then, commands, scripted),
            model,
        )
        tail = nominal[step // period_steps + config.horizon :]
        outcomes = _branch_outcomes(task, plant, play, state, held_then, step, commands, tail)
        states.append(BranchState(index, round(time, 9), nominal_success, outcomes, values))
    return nominal_success, states


def _branch_outcomes(
    task: TaskRegions,
    plant: Simulator,
    play: Callable[..., object],
    state: np.ndarray,
    held: np.ndarray | None,
    step: int,
    commands: np.ndarray,
    tail: np.ndarray,
) -> np.ndarray:
    """Whether each branch succeeds: the plant from ``state`` at ``step`` under one sampled sequence, then ``tail``.

    ``commands`` holds the sampled sequences (one per branch), ``tail`` the nominal commands after
    the controller's horizon, ``held`` the robot targets held at ``step``; ``play`` runs the plant
    to the end under the pushes. Returns one bool per branch.
    """
    outcomes = np.zeros(len(commands), dtype=bool)
    for branch, sequence in enumerate(commands):
        plant.set_state(state)
        if held is not None:
            plant.set_robot_targets(held)
        schedule = np.concatenate([sequence, tail])
        play(schedule, held=held, start_step=step)
        outcomes[branch] = task.is_successful(plant.frame_state())
    return outcomes


def _cost_context(
    task: Task,
    space: CommandSpace,
    trajectory: Trajectory,
    weights: CostWeights,
    config: ControllerConfig,
    seed: np.random.SeedSequence,
    model: MarginPredictor | None,
) -> CostContext:
    """The cost context of the episode's controllers (the nominal friction, margins seeded by ``seed``)."""
    return CostContext(
        task,
        length_scale=space.length_scale,
        weights=weights,
        friction=trajectory.friction,
        drive=trajectory.drive,
        analysis_drive=lambda force: space.analysis_drive(trajectory, force),
        margin_expansions=config.margin_expansions,
        margin_samples=config.samples,
        seed_sequence=seed,
        model=model,
    )


def _score_values(
    scores: Sequence[str],
    task: Task,
    context: CostContext,
    predictions: Any,
    controllers: tuple[Controller, Controller],
    decision: tuple[FrameState, float, np.ndarray | None, np.ndarray, Any],
    model: MarginPredictor | None,
) -> dict[str, np.ndarray]:
    """Every asked score of the sampled sequences at one decision, shape (S,) each (higher is better).

    ``controllers`` holds the study's controller and the one that knows the plant's friction;
    ``decision`` holds the true frame, its time (s), the held targets, the sampled commands and
    whether each is scripted.
    """
    controller, knowing = controllers
    truth, time, held_then, commands, scripted = decision
    values: dict[str, np.ndarray] = {}
    if "task" in scores:
        values["task"] = -task_cost(predictions, context)
    if "margin" in scores:
        values["margin"] = margin_scores(predictions, context, list(range(predictions.n_samples)))
    if "oracle_state" in scores:
        values["oracle_state"] = -task_cost(controller.predict(truth, time, held_then, commands, scripted), context)
    if "oracle_friction" in scores:
        values["oracle_friction"] = -task_cost(knowing.predict(truth, time, held_then, commands, scripted), context)
    if "learned" in scores:
        if model is None:
            raise EnergyMarginError("the learned score needs a model")
        frames = [predictions.frame(sample) for sample in range(predictions.n_samples)]
        capture, success = model.predict(task, frames)
        values["learned"] = np.asarray(capture, dtype=float) + np.asarray(success, dtype=float)
    return values


def branch_study(
    task: Task,
    *,
    n_objects: int,
    episodes: int,
    disturbance: Disturbance,
    seed: int,
    decision_times: Sequence[float],
    config: ControllerConfig | None = None,
    weights: CostWeights | None = None,
    scores: Sequence[str] = ("task", "margin"),
    model: MarginPredictor | None = None,
    on_episode: Callable[[int], None] | None = None,
) -> BranchStudy:
    """Branch the controller's sampled sequences at ``decision_times`` of ``episodes`` episodes.

    Args:
        task: a task with a command space.
        n_objects: objects per episode, >= 1.
        episodes: number of episodes E, >= 1; episode i uses ``SeedSequence(seed).spawn(E)[i]``
            as a control run does.
        disturbance: the plant's disturbance level.
        seed: non-negative integer seed.
        decision_times: episode times at which to branch, s (rounded to control periods).
        config: the controller's settings (samples K, horizon H, period, noise, margin expansions).
        weights: the cost weights of the ``task`` score.
        scores: which of :data:`SCORES` to compute (``margin`` runs K analyses per state).
        model: the learned margin, for the ``learned`` score.
        on_episode: called with each episode's index as it ends.

    """
    check_int("n_objects", n_objects, minimum=1)
    check_int("episodes", episodes, minimum=1)
    check_seed(seed)
    unknown = [name for name in scores if name not in SCORES]
    if unknown:
        raise InvalidParameterError("scores", f"holds unknown {unknown}; choose from {', '.join(SCORES)}")
    if not decision_times or min(decision_times) < 0:
        raise InvalidParameterError("decision_times", "must hold at least one time, none negative")
    config = config or ControllerConfig()
    weights = weights or CostWeights()
    study = BranchStudy(
        settings={
            "task": task.name,
            "n_objects": n_objects,
            "episodes": episodes,
            "disturbance": disturbance.to_dict(),
            "seed": seed,
            "decision_times": [float(time) for time in decision_times],
            "controller": config.to_dict(),
            "weights": asdict(weights),
            "scores": list(scores),
        }
    )
    nominal = []
    for index, child in enumerate(np.random.SeedSequence(seed).spawn(episodes)):
        success, states = branch_episode(
            task,
            index,
            child,
            n_objects=n_objects,
            disturbance=disturbance,
            decision_times=decision_times,
            config=config,
            weights=weights,
            scores=scores,
            model=model,
        )
        nominal.append(success)
        study.states.extend(states)
        if on_episode is not None:
            on_episode(index)
    return BranchStudy(study.settings, study.states, np.array(nominal, dtype=bool))
