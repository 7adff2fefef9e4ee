"""Energy margins inside dm_control: a ``Physics`` scorer and an environment wrapper.

``PhysicsScorer(physics, objects=..., capture=..., success=...)`` scores the state of a
``dm_control.mujoco.Physics`` (``physics.model.ptr`` and ``physics.data.ptr`` are the MuJoCo model
and data it reads, never writes). ``MarginEnvironment(env, ...)`` wraps a ``dm_env`` environment
with a ``physics`` (``dm_control.suite``, ``dm_control.composer``, ``dm_control.manipulation``):
its ``step`` returns the environment's ``TimeStep`` unchanged and, every ``every`` steps, keeps the
scores of the state reached in :attr:`MarginEnvironment.margin` (the same dict as Gymnasium's
``info["energy_margin"]``) and appends them to :attr:`MarginEnvironment.margins`. The robot holds
its last action during the tree's propagation (see
:mod:`energy_margin.integrations.live_model`); given the ``policy`` that drives it, the success
score is continued under that policy to the end of the episode
(:mod:`~energy_margin.integrations.live_policy`).

Needs ``pip install 'energy-margin[dm]'``. dm_control 1.0.50 indexes a few flex fields that MuJoCo
4.0's ``MjModel`` and ``MjData`` no longer have (``flex_vertedge`` and eight more), so building
any of its ``Physics`` fails with ``AttributeError: 'MjModel' object has no attribute
'flex_vertedge'``; importing this module drops those names from dm_control's named-index tables
(:func:`align_dm_control_index`), which only removes ``physics.named`` access to fields that do
not exist.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import mujoco

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.live import MAX_EXPANSIONS
from energy_margin.evaluation.monitor import MonitorCalibration, load_calibration
from energy_margin.integrations.handles import find_mujoco
from energy_margin.integrations.live_model import Hold, LiveModelScorer, LiveOptions
from energy_margin.integrations.live_policy import Policy
from energy_margin.integrations.live_session import LiveSession

__all__ = [
    "MarginEnvironment",
    "PhysicsScorer",
    "align_dm_control_index",
    "episode_steps",
    "physics_handles",
]


def align_dm_control_index() -> list[str]:
    """Drop from dm_control's named-index tables the fields this MuJoCo's structs lack; returns them."""
    try:
        from dm_control.mujoco.wrapper.mjbindings import sizes
    except ImportError:
        return []
    model = mujoco.MjModel.from_xml_string("<mujoco/>")
    structs = {"mjmodel": model, "mjdata": mujoco.MjData(model)}
    dropped = []
    for struct_name, struct in structs.items():
        table = sizes.array_sizes.get(struct_name, {})
        for field in [name for name in table if not hasattr(struct, name)]:
            del table[field]
            dropped.append(f"{struct_name}.{field}")
    return dropped


align_dm_control_index()


def physics_handles(physics: Any) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The ``MjModel`` and ``MjData`` behind a dm_control ``Physics`` or an environment holding one."""
    return find_mujoco(physics)


class PhysicsScorer(LiveModelScorer):
    """A :class:`~energy_margin.integrations.live_model.LiveModelScorer` on a dm_control ``Physics``.

    Args:
        physics: the ``Physics`` (or an environment holding one as ``.physics``).
        **kwargs: the scorer's arguments (``objects``, ``capture``, ``success``, ``scene``, ...).

    """

    def __init__(self, physics: Any, **kwargs: Any) -> None:
        model, _ = physics_handles(physics)
        kwargs.setdefault("origin", type(getattr(physics, "physics", physics)).__name__)
        super().__init__(model, **kwargs)
        self.physics = getattr(physics, "physics", physics)

    def score_physics(self) -> dict[str, Any]:
        """Score the physics' current state."""
        return self.score(physics_handles(self.physics)[1])


def episode_steps(env: Any, step_s: float) -> int | None:
    """Steps of a whole episode of a dm_control environment, or ``None`` when it has no time limit.

    ``dm_control.rl.control.Environment`` counts steps against its ``time_limit`` (``_step_limit``);
    ``dm_control.composer.Environment`` compares the physics' time with it (``_time_limit``, s), so
    its episode ends after ``ceil(time_limit / step_s)`` steps of ``step_s`` seconds.
    """
    step_limit = getattr(env, "_step_limit", None)
    if isinstance(step_limit, int | float) and math.isfinite(step_limit):
        return math.ceil(step_limit)
    time_limit = getattr(env, "_time_limit", None)
    if isinstance(time_limit, int | float) and math.isfinite(time_limit) and step_s > 0:
        return math.ceil(time_limit / step_s - 1e-9)
    return None


class MarginEnvironment:
    """A ``dm_env`` environment whose steps are scored every ``every`` steps (see the module docstring).

    Args:
        env: a dm_control environment with ``physics``.
        objects: object body names or glob patterns.
        capture: the capture set as a scene file's region table.
        success: the success set, likewise.
        scene: a scene file giving objects, perturbation, bounds and both sets instead.
        every: score after every this many steps (>= 1); 0 turns scoring off.
        budget_s: wall-clock budget of one scoring call (reading the state included), s; ``None`` for
            ``max_expansions`` only.
        max_expansions: most tree expansions per call.
        model: a learned margin file to score with instead of the tree.
        hold: ``"action"``, ``"still"`` or ``"coasting"`` (:class:`~energy_margin.integrations.live_model.LiveOptions`).
        seed: root seed of the trees' perturbations.
        record: keep the episode's rows for :meth:`save_episode`.
        perturbation: a scene file's ``[perturbation]`` table.
        config: further analysis settings.
        calibration: a monitor calibration (a loaded ``MonitorCalibration`` or the file of one,
            ``energy-margin monitor --save``); each scored call's ``margin`` then holds ``alarm``.
        policy: the policy driving the robot, ``policy(data) -> ctrl`` on the physics' ``MjData``
            (the actuator controls, shape (nu,): what the task's ``before_step`` makes of an
            action): the success score is continued under it, one command per control step
            (``env.control_timestep()``), from ``continuation`` of the tree's likely states to the
            end of the episode (the environment's time limit; 1 s where there is none).
        continuation: with a policy, the draws continued under it, >= 1.

    """

    def __init__(
        self,
        env: Any,
        *,
        objects: str | list[str] | None = None,
        capture: Mapping[str, Any] | None = None,
        success: Mapping[str, Any] | None = None,
        scene: str | Path | None = None,
        every: int = 1,
        budget_s: float | None = 0.05,
        max_expansions: int = MAX_EXPANSIONS,
        model: Any = None,
        hold: Hold = "action",
        seed: int = 0,
        record: bool = False,
        perturbation: Mapping[str, Any] | None = None,
        config: AnalyzerConfig | None = None,
        calibration: MonitorCalibration | str | Path | None = None,
        policy: Policy | None = None,
        continuation: int = 4,
    ) -> None:
        self.env = env
        control_timestep = getattr(env, "control_timestep", None)
        step_s = float(control_timestep()) if callable(control_timestep) else physics_handles(env)[0].opt.timestep
        self.scorer = PhysicsScorer(
            env,
            objects=objects,
            capture=capture,
            success=success,
            scene=scene,
            perturbation=perturbation,
            margin_model=model,
            options=LiveOptions(budget_s=budget_s, max_expansions=max_expansions, hold=hold, seed=seed, config=config,
                                continuation=continuation),
            origin=type(env).__name__,
            policy=policy,
            policy_period_s=step_s,
        )  # fmt: skip
        if isinstance(calibration, str | Path):
            calibration = load_calibration(calibration)
        self.session = LiveSession(self.scorer, every=every, record=record, calibration=calibration, step_s=step_s,
                                   episode_steps=episode_steps(env, step_s))  # fmt: skip
        # Found once here and again at every reset (a composer task may rebuild its physics there), not per step.
        self._data = physics_handles(env)[1]
        self.margin: dict[str, Any] | None = None
        self.margins: list[dict[str, Any]] = []

    def reset(self) -> Any:
        """Reset the environment; a new episode's margins (the start state's first) and rows."""
        time_step = self.env.reset()
        self._start()
        return time_step

    def _start(self) -> None:
        """A new episode from the environment's current (start) state."""
        self._data = physics_handles(self.env)[1]
        self.margin = self.session.reset(self._data)
        self.margins = [self.margin] if self.margin is not None else []

    def step(self, action: Any) -> Any:
        """Step the environment, then score the state it reached every ``every`` steps.

        A step after the episode's last starts a new episode (dm_env's rule: the environment resets
        itself and returns a ``FIRST`` time step): that is scored as :meth:`reset` scores.
        """
        time_step = self.env.step(action)
        if time_step.first():
            self._start()
            return time_step
        margin = self.session.step(self._data)
        if margin is not None:
            self.margin = margin
            self.margins.append(margin)
        return time_step

    def save_episode(self, path: str | Path) -> Path:
        """Write the recorded episode as an ``.npz`` roll-out for ``energy-margin record``."""
        return self.session.save_episode(path)

    def __getattr__(self, name: str) -> Any:
        """Everything else (``action_spec``, ``observation_spec``, ``physics`` ...) is the environment's."""
        return getattr(self.env, name)
