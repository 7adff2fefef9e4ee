"""A sampling-based predictive controller (MPPI) over a task's command space.

Every control period the controller resets its nominal model (the task's scene at the nominal
friction) to the observed state, samples ``samples`` command sequences of ``horizon`` periods
around its current plan, rolls them out together through ``mujoco.rollout``, scores each with
its cost, and moves the plan to the exp(-cost / temperature)-weighted mean of the samples. It
executes the plan's first command and shifts the plan by one period.

The plan is a deviation from the task's scripted command at each period (the command space's
``nominal``): a new period enters the plan with no deviation, so without a reason to differ
the controller does what the script does (a scoop gripper closes, then lifts, on time).
"""

from __future__ import annotations

import time as clock
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from energy_margin.control.commands import CommandSpace
from energy_margin.control.costs import CostContext, CostFunction, Predictions
from energy_margin.errors import Constraint, check_fields, constrained
from energy_margin.sim.base import BatchedRollout, require
from energy_margin.tasks import Task, Trajectory
from energy_margin.world.state import FrameState

__all__ = [
    "Controller",
    "ControllerConfig",
]

#: A finite number > 0.
_POSITIVE = Constraint("float", minimum=0.0, exclusive_minimum=True)


@dataclass(frozen=True)
class ControllerConfig:
    """Settings of the MPPI controller.

    Attributes:
        samples: command sequences sampled per decision K (the first is the plan itself).
        horizon: command periods per sequence H.
        period: control period: a command is held this long, s.
        noise: standard deviation of the sampled command changes, as a fraction of each
            component's half range.
        temperature: softmax temperature, in cost units (a task length scale of distance): where
            the samples' costs differ by much less, they are weighted alike and the plan stays.
        correlation: correlation of a sample's noise between consecutive periods, in [0, 1).
        margin_expansions: expansions of each short energy-margin analysis (``margin`` cost).
        margin_samples: sequences analysed per decision (``margin`` cost).
        lookahead: command periods the prediction goes on past the horizon with the script's
            commands (no sampled deviation), cut at the episode's end; the cost then sees the
            states of the horizon and of the look-ahead (0: the horizon only).

    """

    samples: int = constrained(12, Constraint("int", minimum=1))
    horizon: int = constrained(4, Constraint("int", minimum=1))
    period: float = constrained(0.1, _POSITIVE)
    noise: float = constrained(0.3, _POSITIVE)
    temperature: float = constrained(0.1, _POSITIVE)
    correlation: float = constrained(0.8, Constraint("float", minimum=0.0, maximum=1.0, exclusive_maximum=True))
    margin_expansions: int = constrained(20, Constraint("int", minimum=1))
    margin_samples: int = constrained(4, Constraint("int", minimum=1))
    lookahead: int = constrained(0, Constraint("int", minimum=0))

    def __post_init__(self) -> None:
        # Each field's constraint is declared once, beside its default (the command line takes both).
        check_fields(self)

    def to_dict(self) -> dict[str, Any]:
        """The settings as a JSON-ready dict."""
        return asdict(self)


class Controller:
    """MPPI over the command space of one episode's task, on the nominal model.

    Args:
        task: the task.
        space: its command space.
        trajectory: the episode's start (its friction is the controller's nominal friction).
        cost: the cost function.
        context: what the cost needs.
        config: the controller's settings.
        rng: the sampling generator.

    """

    def __init__(
        self,
        task: Task,
        space: CommandSpace,
        trajectory: Trajectory,
        cost: CostFunction,
        context: CostContext,
        config: ControllerConfig,
        rng: np.random.Generator,
    ) -> None:
        self.task, self.space, self.cost, self.context, self.config, self.rng = (
            task,
            space,
            cost,
            context,
            config,
            rng,
        )
        n_objects = trajectory.initial.n_objects
        self.model = task.make_simulator(n_objects, trajectory.friction, trajectory.drive, "mujoco")
        self.propagator = require(self.model, BatchedRollout, purpose="the controller").rollout_propagator(1)
        self.dt = self.model.timestep
        self.period_steps = max(1, round(config.period / self.dt))
        # The plan: deviation of each period's command from the script's, shape (H, m).
        self.plan = np.zeros((config.horizon, space.dimension))
        self.trajectory = trajectory
        self.decisions = 0
        self.seconds = 0.0

    def sample(self, time: float) -> tuple[np.ndarray, np.ndarray]:
        """Command sequences around the plan at ``time`` (s), and the script's commands.

        Returns:
            The sampled sequences, shape (K, H, m), clipped to the bounds (sample 0 is the plan
            itself), and the script's command of each period, shape (H, m).

        """
        config, space = self.config, self.space
        half_range = 0.5 * (space.high - space.low)
        # Sample 0 is the plan itself, so the weighted mean never ignores the current plan.
        # Noise correlated along the horizon (an AR(1) process): a sequence changes its command
        # smoothly rather than jittering from one period to the next.
        white = self.rng.normal(0.0, config.noise, (config.samples, config.horizon, space.dimension))
        noise = np.empty_like(white)
        noise[:, 0] = white[:, 0]
        innovation = np.sqrt(1.0 - config.correlation**2)
        for h in range(1, config.horizon):
            noise[:, h] = config.correlation * noise[:, h - 1] + innovation * white[:, h]
        scale = np.ones(space.dimension) if space.noise_scale is None else np.asarray(space.noise_scale)
        noise *= half_range * scale
        noise[0] = 0.0
        period = self.period_steps * self.dt
        scripted = np.stack([space.nominal(self.trajectory, time + h * period) for h in range(config.horizon)])
        return space.clip(scripted[None] + self.plan[None] + noise), scripted

    def predict(
        self, observed: FrameState, time: float, held: np.ndarray | None, commands: np.ndarray, scripted: np.ndarray
    ) -> Predictions:
        """The nominal model's states under ``commands`` (K, H, m) from ``observed`` at ``time`` (s).

        With a ``lookahead`` of L periods, each sequence goes on with the script's commands for
        up to L more periods (not past the episode's end), and the predictions hold the states
        at the end of all H + L periods.

        Args:
            observed: the state the controller sees.
            time: episode time, s.
            held: servo targets held before the sequences, shape (n_robot_dofs,), or ``None``.
            commands: command sequences, shape (K, H, m).
            scripted: the script's command of each period, shape (H, m).

        """
        space = self.space
        self.model.reset(observed)
        if held is not None:
            self.model.set_robot_targets(held)
        state = self.propagator.current_state()
        half_range = 0.5 * (space.high - space.low)
        deviations = (commands - scripted[None]) / half_range
        period = self.period_steps * self.dt
        horizon = commands.shape[1]
        remaining = int(np.ceil((self.task.n_steps * self.dt - time) / period - 1e-9)) - horizon
        lookahead = max(0, min(self.config.lookahead, remaining))
        if lookahead:
            after = np.stack(
                [space.nominal(self.trajectory, time + h * period) for h in range(horizon, horizon + lookahead)]
            )
            commands = np.concatenate([commands, np.broadcast_to(after, (len(commands), *after.shape))], axis=1)
        inputs = space.inputs(commands, held=held, start_time=time, dt=self.dt, period_steps=self.period_steps)
        states, _ = self.propagator.roll_commands(state, inputs.forces, inputs.targets, inputs.ctrl)
        knots = states[:, self.period_steps - 1 :: self.period_steps]
        k, periods = knots.shape[:2]
        pos, quat, vel, robot_q, robot_v = self.propagator.object_states(knots.reshape(k * periods, -1))
        return Predictions(
            object_pos=pos.reshape(k, periods, *pos.shape[1:]),
            object_quat=quat.reshape(k, periods, *quat.shape[1:]),
            object_vel=vel.reshape(k, periods, *vel.shape[1:]),
            robot_q=robot_q.reshape(k, periods, -1),
            robot_v=robot_v.reshape(k, periods, -1),
            commands=deviations,
            forces=inputs.forces[:, -1],
            targets=None if inputs.targets is None else inputs.targets[:, -1],
            ctrl=None if inputs.ctrl is None else inputs.ctrl[:, -1],
            end_time=time + periods * period,
        )

    def decide(self, observed: FrameState, time: float, held: np.ndarray | None) -> np.ndarray:
        """The command (m,) to hold for the next period, from the observed state at ``time`` (s)."""
        started = clock.perf_counter()
        config, space = self.config, self.space
        commands, scripted = self.sample(time)
        predictions = self.predict(observed, time, held, commands, scripted)
        costs = np.asarray(self.cost(predictions, self.context), dtype=float)
        weights = np.exp(-(costs - costs.min()) / config.temperature)
        weights /= weights.sum()
        chosen = space.clip(np.einsum("k,khm->hm", weights, commands))
        command = chosen[0].copy()
        self.plan = np.concatenate([(chosen - scripted)[1:], np.zeros((1, space.dimension))])
        self.decisions += 1
        self.seconds += clock.perf_counter() - started
        return command
