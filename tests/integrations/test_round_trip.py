"""Round trip: an episode recorded through the Gymnasium wrapper, turned into a dataset by ``record`` and
analysed, against ``generate`` + ``analyze`` of the same motion on the same scene."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium")

from energy_margin.analysis.frame import AnalyzerConfig  # noqa: E402
from energy_margin.analysis.run import analyze  # noqa: E402
from energy_margin.data.dataset import load_dataset  # noqa: E402
from energy_margin.data.generate import generate_dataset  # noqa: E402
from energy_margin.data.record import record_dataset  # noqa: E402
from energy_margin.data.scores_file import load_scores  # noqa: E402
from energy_margin.integrations.gymnasium import MarginWrapper  # noqa: E402
from energy_margin.tasks import get_task  # noqa: E402
from tiny_scene import TINY_SCENE, write_tiny_scene  # noqa: E402


class MocapPusherEnv(gymnasium.Env):  # type: ignore[misc]
    """A user's own environment: the action is the mocap pusher's position; one physics step per step."""

    def __init__(self, model_path: Path) -> None:
        self.model = mujoco.MjModel.from_xml_path(str(model_path))
        self.data = mujoco.MjData(self.model)
        self.action_space = gymnasium.spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float64)
        size = self.model.nq + self.model.nv
        self.observation_space = gymnasium.spaces.Box(-np.inf, np.inf, shape=(size,), dtype=np.float64)

    def _observation(self) -> np.ndarray:
        return np.concatenate([self.data.qpos, self.data.qvel])

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        mujoco.mj_resetData(self.model, self.data)
        options = options or {}
        self.data.qpos[:] = options["qpos"]
        self.data.mocap_pos[:] = options["mocap_pos"]
        mujoco.mj_forward(self.model, self.data)
        return self._observation(), {}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        self.data.mocap_pos[0] = action
        mujoco.mj_step(self.model, self.data)
        return self._observation(), 0.0, False, False, {}


def test_recorded_episode_scores_as_the_generated_one(tmp_path: Path) -> None:
    # Without friction randomisation, so that record's friction (the model's) is generate's too.
    scene_text = TINY_SCENE.replace("[randomize]\nfriction = [0.3, 0.6]\n", "[randomize]\n")
    scene = write_tiny_scene(tmp_path / "scene", scene=scene_text)
    frames = 4
    generated = generate_dataset(
        "scene",
        n_objects=2,
        n_trajectories=1,
        n_frames=frames,
        seed=0,
        out=tmp_path / "generated",
        task_config={"scene_file": str(scene)},
    )
    task = get_task("scene", {"scene_file": str(scene)})
    start = generated.frame(0, 0)
    qpos = np.array(task.loaded.initial_qpos)
    for index, joint in enumerate(task.loaded.object_joints):
        address = task.loaded.model.jnt_qposadr[joint]
        qpos[address : address + 3] = start.object_pos[index]
        qpos[address + 3 : address + 7] = start.object_quat[index]
    drive = np.ones(2)
    dt = float(task.loaded.model.opt.timestep)
    steps = round(task.config.duration / dt)
    env = MarginWrapper(MocapPusherEnv(scene.parent / "model.xml"), scene=scene, every=0, record=True)
    first = task.model_command(drive, 0.0)
    env.reset(options={"qpos": qpos, "mocap_pos": first.mocap_pos})
    for step in range(steps):
        env.step(task.model_command(drive, step * dt).mocap_pos[0])
    episode = env.save_episode(tmp_path / "episode.npz")
    recorded = record_dataset(scene, [episode], n_frames=frames, out=tmp_path / "recorded")

    # The same frames: states equal to rounding of the episode clock (data.time sums dt step by step).
    assert np.allclose(recorded.arrays["frame_time"], generated.arrays["frame_time"], rtol=0, atol=1e-12)
    for name in ("object_pos", "object_quat", "object_vel", "robot_q", "robot_v", "captured", "in_success"):
        assert np.allclose(recorded.arrays[name], generated.arrays[name], rtol=0, atol=1e-12), name

    config = AnalyzerConfig(expansions=40)
    for directory in ("generated", "recorded"):
        analyze(tmp_path / directory, config, seed=5, workers=1)
    ours, theirs = load_scores(tmp_path / "recorded"), load_scores(tmp_path / "generated")
    for column in ("capture_score", "success_score", "nodes"):
        assert np.allclose(ours[column], theirs[column], rtol=0, atol=1e-9), column
    assert load_dataset(tmp_path / "recorded").n_frames == frames
