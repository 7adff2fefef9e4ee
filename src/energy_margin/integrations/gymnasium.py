"""A Gymnasium wrapper that adds the energy margins of the current state to ``info``.

``MarginWrapper(env, objects=..., capture=..., success=...)`` works on any Gymnasium environment
in which :func:`~energy_margin.integrations.handles.find_mujoco` finds a MuJoCo ``MjModel`` and
``MjData``: Gymnasium's own MuJoCo environments, gymnasium-robotics, Meta-World, robosuite's
``GymWrapper`` (through ``env.sim``) and dm_control-based ones such as LeRobot's gym-aloha
(through their ``physics``). Every
``every`` steps it scores the state reached by the step with
:class:`~energy_margin.integrations.live_model.LiveModelScorer` (the tree within ``budget_s``, or a
learned margin) and adds ``info["energy_margin"]``, a dict with ``capture_score``,
``success_score``, ``expansions``, ``nodes``, ``ms``, ``stopped_by`` and ``seed`` (``reset``'s
``info`` holds those of the start state). During the tree's
propagation the robot holds the last action (zero-order hold); ``hold="still"`` holds it where it
is instead. Scoring only reads the environment's state: observations, rewards and the
environment's random numbers are the same with and without the wrapper.

With ``record=True`` the wrapper keeps the episode's rows (``time``, ``qpos``, ``qvel``,
``ctrl``, ``mocap_pos``, ``mocap_quat``; the state after ``reset`` and after every step) and
:meth:`MarginWrapper.save_episode` writes them as the roll-out ``energy-margin record`` reads.

Needs ``pip install 'energy-margin[gymnasium]'``.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any, SupportsFloat

try:
    import gymnasium
except ImportError as error:  # pragma: no cover - the message is the test
    raise ImportError(
        "energy_margin.integrations.gymnasium needs Gymnasium: pip install 'energy-margin[gymnasium]'"
    ) from error

import mujoco

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.live import MAX_EXPANSIONS
from energy_margin.errors import EnergyMarginError
from energy_margin.evaluation.monitor import MonitorCalibration, load_calibration
from energy_margin.integrations.handles import find_mujoco
from energy_margin.integrations.live_model import Hold, LiveModelScorer, LiveOptions
from energy_margin.integrations.live_policy import Policy
from energy_margin.integrations.live_session import LiveSession

__all__ = [
    "MarginWrapper",
    "environment_name",
    "make_environment",
    "mujoco_handles",
]


def mujoco_handles(env: Any, *, what: str | None = None) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The ``MjModel`` and ``MjData`` behind ``env`` (:func:`~energy_margin.integrations.handles.find_mujoco`)."""
    return find_mujoco(env, what=what or environment_name(env))


def make_environment(identifier: str, env_kwargs: Mapping[str, Any] | None = None) -> gymnasium.Env:
    """``gymnasium.make`` of ``identifier`` (``ENV_ID`` or ``MODULE:ENV_ID``) with ``env_kwargs``.

    ``MODULE`` is imported first: the package that registers the environment's namespace
    (``metaworld:Meta-World/MT1``, ``gymnasium_robotics:FetchPickAndPlace-v4``,
    ``gym_aloha:gym_aloha/AlohaInsertion-v0``).

    Raises:
        EnergyMarginError: a module that cannot be imported, an unknown id, keyword arguments the
            environment refuses (one line each).

    """
    import importlib

    module, _, name = identifier.rpartition(":")
    if module:
        try:
            importlib.import_module(module)
        except ImportError as error:
            raise EnergyMarginError(
                f"{identifier}: module {module!r} cannot be imported ({' '.join(str(error).split())}); install the "
                "package that registers the environment"
            ) from None
    try:
        return gymnasium.make(name, **dict(env_kwargs or {}))
    except gymnasium.error.Error as error:
        hint = "" if module else " (give the module that registers it: MODULE:ENV_ID, e.g. metaworld:Meta-World/MT1)"
        raise EnergyMarginError(f"{identifier}: {' '.join(str(error).split())}{hint}") from None
    except Exception as error:  # an environment's constructor raises what it likes for bad keyword arguments
        given = f" with {dict(env_kwargs or {})}" if env_kwargs else ""
        raise EnergyMarginError(
            f"{identifier}{given}: {type(error).__name__}: {' '.join(str(error).split())}"
        ) from None


def environment_name(env: Any) -> str:
    """The environment's registered id (``Pusher-v5``) or its class name."""
    spec = getattr(env, "spec", None)
    identifier = getattr(spec, "id", None)
    return str(identifier) if identifier else type(getattr(env, "unwrapped", env)).__name__


class MarginWrapper(gymnasium.Wrapper):
    """Adds ``info["energy_margin"]`` every ``every`` steps (see the module docstring).

    Args:
        env: an environment holding a MuJoCo model and data (see the module docstring).
        objects: object body names or glob patterns.
        capture: the capture set as a scene file's region table (or ``{"region", "at_least"}``).
        success: the success set, likewise.
        scene: a scene file giving objects, perturbation, bounds and both sets instead.
        every: score after every this many steps (>= 1); 0 turns scoring off (recording stays).
        budget_s: wall-clock budget of one scoring call (reading the state included), s; ``None`` for
            ``max_expansions`` only.
        max_expansions: most tree expansions per call.
        model: a learned margin file (``energy-margin learn``) to score with instead of the tree.
        hold: ``"action"`` (the last action is held during propagation), ``"still"`` or ``"coasting"``.
        seed: root seed of the trees' perturbations.
        record: keep the episode's rows for :meth:`save_episode`.
        perturbation: a scene file's ``[perturbation]`` table.
        config: further analysis settings.
        calibration: a monitor calibration (``energy-margin monitor --save``: a loaded
            :class:`~energy_margin.evaluation.monitor.MonitorCalibration` or the file of one);
            each scored call then adds ``alarm`` to ``info["energy_margin"]``.
        policy: the policy driving the robot, ``policy(data) -> ctrl`` on the environment's
            ``MjData`` (:mod:`~energy_margin.integrations.live_policy`): the success score is
            continued under it, one command per environment step (``dt``), from ``continuation``
            of the tree's likely states to the end of the episode (the time limit of
            ``env.spec.max_episode_steps``; 1 s where there is none).
        continuation: with a policy, the draws continued under it, >= 1.

    """

    def __init__(
        self,
        env: gymnasium.Env,
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
        super().__init__(env)
        # Found once here and again at every reset (robosuite rebuilds its simulation there), not per step.
        mj_model, self._data = mujoco_handles(env)
        # The environment's time per step (Gymnasium's MuJoCo environments: frame_skip x timestep).
        step_s = float(getattr(env.unwrapped, "dt", mj_model.opt.timestep))
        scorer = LiveModelScorer(
            mj_model,
            objects=objects,
            capture=capture,
            success=success,
            scene=scene,
            perturbation=perturbation,
            margin_model=model,
            options=LiveOptions(budget_s=budget_s, max_expansions=max_expansions, hold=hold, seed=seed, config=config,
                                continuation=continuation),
            origin=environment_name(env),
            policy=policy,
            policy_period_s=step_s,
        )  # fmt: skip
        if isinstance(calibration, str | Path):
            calibration = load_calibration(calibration)
        spec = getattr(env, "spec", None)
        self.session = LiveSession(scorer, every=every, record=record, calibration=calibration, step_s=step_s,
                                   episode_steps=getattr(spec, "max_episode_steps", None))  # fmt: skip
        self.scorer = scorer

    @property
    def steps(self) -> int:
        """Steps since the last reset."""
        return self.session.steps

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        """Reset the environment (a new recorded episode); ``info["energy_margin"]`` scores the start state."""
        observation, info = self.env.reset(**kwargs)
        self._data = mujoco_handles(self.env)[1]
        margin = self.session.reset(self._data)
        if margin is not None:
            info = {**info, "energy_margin": margin}
        return observation, info

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        """Step the environment, then score the state it reached every ``every`` steps."""
        observation, reward, terminated, truncated, info = self.env.step(action)
        margin = self.session.step(self._data)
        if margin is not None:
            info = {**info, "energy_margin": margin}
        return observation, reward, terminated, truncated, info

    def labels(self) -> tuple[bool, bool]:
        """Whether the current state is in the capture set and in the success set."""
        return self.scorer.labels(self._data)

    def save_episode(self, path: str | Path) -> Path:
        """Write the recorded episode as an ``.npz`` roll-out for ``energy-margin record``."""
        return self.session.save_episode(path)
