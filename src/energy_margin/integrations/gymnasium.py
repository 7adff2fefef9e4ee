"""A Gymnasium wrapper that adds the energy margins of the current state to ``info``.

``MarginWrapper(env, objects=..., capture=..., success=...)`` works on any environment whose
``env.unwrapped`` holds a MuJoCo ``model`` and ``data`` (Gymnasium's own MuJoCo environments and
those written the same way, as gymnasium-robotics' and Meta-World's are). Every
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
from energy_margin.integrations.live_model import Hold, LiveModelScorer, LiveOptions, LiveSession


def mujoco_handles(env: Any, *, what: str = "the environment") -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The ``MjModel`` and ``MjData`` of ``env.unwrapped`` (one line naming ``what`` when there are none)."""
    inner = getattr(env, "unwrapped", env)
    model, data = getattr(inner, "model", None), getattr(inner, "data", None)
    if not isinstance(model, mujoco.MjModel) or not isinstance(data, mujoco.MjData):
        name = type(inner).__name__
        raise EnergyMarginError(
            f"{what} ({name}) has no MuJoCo model: env.unwrapped must hold a mujoco.MjModel 'model' and "
            "mujoco.MjData 'data' (Gymnasium's MuJoCo environments do)"
        )
    return model, data


def environment_name(env: Any) -> str:
    """The environment's registered id (``Pusher-v5``) or its class name."""
    spec = getattr(env, "spec", None)
    identifier = getattr(spec, "id", None)
    return str(identifier) if identifier else type(getattr(env, "unwrapped", env)).__name__


class MarginWrapper(gymnasium.Wrapper):
    """Adds ``info["energy_margin"]`` every ``every`` steps (see the module docstring).

    Args:
        env: an environment whose ``unwrapped`` holds a MuJoCo ``model`` and ``data``.
        objects: object body names or glob patterns.
        capture: the capture set as a scene file's region table (or ``{"region", "at_least"}``).
        success: the success set, likewise.
        scene: a scene file giving objects, perturbation, bounds and both sets instead.
        every: score after every this many steps (>= 1); 0 turns scoring off (recording stays).
        budget_s: wall-clock budget of one scoring call (reading the state included), s; ``None`` for
            ``max_expansions`` only.
        max_expansions: most tree expansions per call.
        model: a learned margin file (``energy-margin learn``) to score with instead of the tree.
        hold: ``"action"`` (the last action is held during propagation) or ``"still"``.
        seed: root seed of the trees' perturbations.
        record: keep the episode's rows for :meth:`save_episode`.
        perturbation: a scene file's ``[perturbation]`` table.
        config: further analysis settings.

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
    ) -> None:
        super().__init__(env)
        mj_model, _ = mujoco_handles(env)
        scorer = LiveModelScorer(
            mj_model,
            objects=objects,
            capture=capture,
            success=success,
            scene=scene,
            perturbation=perturbation,
            margin_model=model,
            options=LiveOptions(budget_s=budget_s, max_expansions=max_expansions, hold=hold, seed=seed, config=config),
            origin=environment_name(env),
        )
        self.session = LiveSession(scorer, every=every, record=record)
        self.scorer = scorer

    @property
    def steps(self) -> int:
        """Steps since the last reset."""
        return self.session.steps

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        """Reset the environment (a new recorded episode); ``info["energy_margin"]`` scores the start state."""
        observation, info = self.env.reset(**kwargs)
        margin = self.session.reset(mujoco_handles(self.env)[1])
        if margin is not None:
            info = {**info, "energy_margin": margin}
        return observation, info

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        """Step the environment, then score the state it reached every ``every`` steps."""
        observation, reward, terminated, truncated, info = self.env.step(action)
        margin = self.session.step(mujoco_handles(self.env)[1])
        if margin is not None:
            info = {**info, "energy_margin": margin}
        return observation, reward, terminated, truncated, info

    def labels(self) -> tuple[bool, bool]:
        """Whether the current state is in the capture set and in the success set."""
        return self.scorer.labels(mujoco_handles(self.env)[1])

    def save_episode(self, path: str | Path) -> Path:
        """Write the recorded episode as an ``.npz`` roll-out for ``energy-margin record``."""
        return self.session.save_episode(path)
