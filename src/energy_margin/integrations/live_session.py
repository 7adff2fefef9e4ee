"""What a live wrapper does around an episode: score every few steps, raise the alarm, record the rows.

:class:`LiveSession` is shared by :class:`~energy_margin.integrations.gymnasium.MarginWrapper` and
:class:`~energy_margin.integrations.dm_control.MarginEnvironment`: it scores the state after a
reset and after every ``every``-th step with a
:class:`~energy_margin.integrations.live_model.LiveModelScorer`, adds the monitor's alarm, and
keeps the rows. :class:`EpisodeRecorder` keeps ``time``, ``qpos``, ``qvel``, ``ctrl``,
``mocap_pos`` and ``mocap_quat`` of every recorded step and writes them as the ``.npz`` roll-out
that ``energy-margin record`` turns into a dataset.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from energy_margin.compat import save_npz
from energy_margin.errors import EnergyMarginError, check_positive_int
from energy_margin.evaluation.live_calibration import live_scores
from energy_margin.evaluation.monitor import LiveAlarm, MonitorCalibration
from energy_margin.integrations.live_model import LiveModelScorer
from energy_margin.runs.files import atomic_path
from energy_margin.sim.mujoco_audit import WARNINGS_ARRAY, warning_numbers

__all__ = ["EpisodeRecorder", "LiveSession"]


class EpisodeRecorder:
    """The rows of one episode in the roll-out layout of ``energy-margin record``.

    ``time`` is measured from the first recorded row (the motion's clock starts at 0 there).
    """

    def __init__(self) -> None:
        self.rows: dict[str, list[np.ndarray]] = {}
        self._start = 0.0

    def clear(self) -> None:
        """Forget every row (a new episode)."""
        self.rows = {}

    def add(self, data: mujoco.MjData) -> None:
        """Append the state held in ``data`` (only read)."""
        if not self.rows:
            self._start = float(data.time)
        values = {
            "time": np.array(float(data.time) - self._start),
            "qpos": np.array(data.qpos, dtype=float),
            "qvel": np.array(data.qvel, dtype=float),
            "ctrl": np.array(data.ctrl, dtype=float),
            "mocap_pos": np.array(data.mocap_pos, dtype=float),
            "mocap_quat": np.array(data.mocap_quat, dtype=float),
            # MuJoCo's counts of its physics warnings: ``record`` refuses a roll-out that raised one.
            WARNINGS_ARRAY: warning_numbers(data).astype(float),
        }
        for name, value in values.items():
            self.rows.setdefault(name, []).append(value)

    def __len__(self) -> int:
        return len(self.rows.get("time", ()))

    def arrays(self) -> dict[str, np.ndarray]:
        """The recorded arrays: time (n,), qpos (n, nq), qvel (n, nv), ctrl (n, nu), mocap_pos/quat, warnings (n, 7)."""
        if not self.rows:
            raise EnergyMarginError("no step has been recorded: reset the environment and step it first")
        return {name: np.stack(rows) for name, rows in self.rows.items()}

    def save(self, path: str | Path) -> Path:
        """Write the episode as an ``.npz`` roll-out (atomically) and return its path."""
        path = Path(path)
        arrays = self.arrays()
        path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(path) as temporary, temporary.open("wb") as stream:
            save_npz(stream, arrays)
        return path


class LiveSession:
    """What a wrapper does around an episode: score every ``every`` steps (and at reset), record rows.

    Shared by :class:`~energy_margin.integrations.gymnasium.MarginWrapper` and
    :class:`~energy_margin.integrations.dm_control.MarginEnvironment`; each gives it the ``MjData``
    after its environment's reset or step.

    Args:
        scorer: the scorer of the environment's model.
        every: score after every this many steps (>= 1), and at reset; 0 never scores.
        record: keep the episode's rows.
        calibration: a margin calibration of ``energy-margin monitor``: every scored call adds
            ``alarm`` (:class:`~energy_margin.evaluation.monitor.LiveAlarm`; the reset's call is frame 0).
        step_s: the environment's time per step, s.
        episode_steps: steps of a whole episode (its time limit), or ``None``: with a policy, a
            scored call's continuations then run to the end of the episode, ``(episode_steps -
            steps) * step_s`` ahead, else the scorer's ``horizon_s``.

    """

    def __init__(
        self,
        scorer: LiveModelScorer,
        *,
        every: int,
        record: bool,
        calibration: MonitorCalibration | None = None,
        step_s: float = 0.0,
        episode_steps: int | None = None,
    ) -> None:
        check_positive_int("every", every, minimum=0)
        self.scorer = scorer
        self.every = every
        self.step_s = step_s
        self.episode_steps = episode_steps
        self.recorder = EpisodeRecorder() if record else None
        self.steps = 0
        self.alarm = LiveAlarm(calibration) if calibration is not None else None

    def _scored(self, data: mujoco.MjData) -> dict[str, Any]:
        """The scores of the state in ``data``, with ``alarm`` when a calibration watches them."""
        left = None if self.episode_steps is None else (self.episode_steps - self.steps) * self.step_s
        scores = self.scorer.score(data, horizon_s=left)
        if self.alarm is not None:  # a capture alarm watches the tree's own capture score, as calibrated
            scores["alarm"] = self.alarm.update(*live_scores(scores))
        return scores

    def reset(self, data: mujoco.MjData) -> dict[str, Any] | None:
        """A new episode from the state in ``data``: its scores (``None`` when scoring is off)."""
        self.steps = 0
        if self.alarm is not None:
            self.alarm.reset()
        if self.recorder is not None:
            self.recorder.clear()
            self.recorder.add(data)
        return self._scored(data) if self.every else None

    def step(self, data: mujoco.MjData) -> dict[str, Any] | None:
        """The state after one more step: its scores on every ``every``-th step, else ``None``."""
        self.steps += 1
        if self.recorder is not None:
            self.recorder.add(data)
        if self.every and self.steps % self.every == 0:
            return self._scored(data)
        return None

    def save_episode(self, path: str | Path) -> Path:
        """Write the recorded episode as an ``.npz`` roll-out for ``energy-margin record``."""
        if self.recorder is None:
            raise EnergyMarginError("the wrapper does not record: create it with record=True")
        return self.recorder.save(path)
