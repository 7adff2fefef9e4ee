"""gymnasium-robotics 1.4.2's FetchPickAndPlace-v4 scored live by MarginWrapper (examples/fetch_pick_and_place).

The stack leg: ``pip install . -r ci/stacks/gymnasium_robotics.txt`` (MuJoCo 3.11.0: gymnasium-robotics
1.4.2 fails on MuJoCo 3.12 and later in its own ``set_joint_qpos``), then
``ENERGY_MARGIN_STACK_LEG=gymnasium_robotics pytest tests/stacks/test_gymnasium_robotics.py``.
"""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest
from stack_legs import mujoco_version, require, skip_unless

LEG = "gymnasium_robotics"
require(
    "gymnasium_robotics",
    leg=LEG,
    reason="the gymnasium-robotics stack is not installed (pip install . -r ci/stacks/gymnasium_robotics.txt)",
)
skip_unless(
    mujoco_version() < (3, 12),
    leg=LEG,
    reason="gymnasium-robotics 1.4.2 fails on MuJoCo >= 3.12 (set_joint_qpos asserts a hinge or slide joint); "
    "its leg pins mujoco==3.11.0 (ci/stacks/gymnasium_robotics.txt)",
)
pytest.importorskip("PIL", reason="the example draws its picture with Pillow (a dependency of gymnasium-robotics)")

from energy_margin.data.dataset import load_dataset  # noqa: E402
from energy_margin.integrations.gymnasium import MarginWrapper  # noqa: E402

FOLDER = Path(__file__).resolve().parents[2] / "examples" / "fetch_pick_and_place"


def _module(name: str) -> ModuleType:
    spec = importlib.util.spec_from_file_location(f"fetch_pick_and_place_{name}", FOLDER / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


live_scores = _module("live_scores")


def _episode(env, seed: int, noise: float, steps: int) -> tuple[list, list, list]:
    """Observations, rewards and infos of one scripted episode."""
    scripted = live_scores.policy.ScriptedPickAndPlace(noise, np.random.default_rng(seed))
    observation, info = env.reset(seed=seed)
    observations, rewards, infos = [observation], [], [info]
    for _ in range(steps):
        observation, reward, _, _, info = env.step(scripted(observation))
        observations.append(observation)
        rewards.append(reward)
        infos.append(info)
    return observations, rewards, infos


def test_wrapper_scores_without_changing_the_environment(tmp_path: Path) -> None:
    steps = 30
    plain = _episode(live_scores.make_env(), 7, 0.1, steps)
    env = live_scores.make_env()
    scene, same_model = live_scores.write_scene(env, tmp_path)
    assert same_model  # the scene's model compiles to the model the environment runs
    wrapper = MarginWrapper(env, scene=scene, every=1, budget_s=None, max_expansions=8, record=True, seed=0)
    wrapped = _episode(wrapper, 7, 0.1, steps)
    for before, after in zip(plain[0], wrapped[0], strict=True):
        assert before.keys() == after.keys()
        for key in before:
            np.testing.assert_array_equal(before[key], after[key])
    assert plain[1] == wrapped[1]
    margins = [info["energy_margin"] for info in wrapped[2]]
    assert len(margins) == steps + 1
    for margin in margins:
        assert 0.0 <= margin["capture_score"] <= 1.0 and 0.0 <= margin["success_score"] <= 1.0
        assert 1 <= margin["expansions"] <= 8 and margin["ms"] > 0
    # The policy grasps the block: the state is in the capture set and the live capture score says so.
    assert any(score["capture_score"] > 0.5 for score in margins[10:])
    assert margins[0]["capture_score"] == 0.0  # the block starts at least 10 cm from the gripper
    episode = wrapper.save_episode(tmp_path / "episode.npz")
    with np.load(episode) as rollout:
        assert rollout["qpos"].shape == (steps + 1, env.unwrapped.model.nq)
        np.testing.assert_array_equal(rollout["qpos"][-1], env.unwrapped.data.qpos)


def test_example_end_to_end(tmp_path: Path) -> None:
    out = tmp_path / "run"
    returned = live_scores.main(["--episodes", "3", "--out", str(out), "--expansions", "10", "--budget", "0.02"])
    results = json.loads((out / "results.json").read_text())
    assert results == json.loads(json.dumps(returned))
    assert results["same_model"] and results["mujoco"] == ".".join(map(str, mujoco_version()))
    timing = results["timing"]
    assert timing["calls"] == 3 * live_scores.SCORED and timing["mean_expansions"] >= 1
    for episode in results["live"]:
        assert episode["steps"] == list(range(0, live_scores.STEPS + 1, live_scores.EVERY))
        for score in episode["scores"]:
            assert 0.0 <= score["capture_score"] <= 1.0 and 0.0 <= score["success_score"] <= 1.0
    # record -> analyze -> evaluate wrote their files, and the evaluation has its verdict.
    dataset = load_dataset(out / "dataset")
    for name in ("dataset.json", "scores.csv"):
        assert (out / "dataset" / name).stat().st_size > 0
    assert dataset.arrays["captured"].shape == (3, live_scores.SCORED)
    evaluation = results["evaluate"]
    assert evaluation["n_trajectories"] == 3 and evaluation["n_frames"] == 3 * live_scores.SCORED
    assert set(evaluation["verdict"]) >= {"capture_ap", "success_ap"}
    assert "verdict" in results["evaluate_text"]
    # The scene's success set is the environment's own criterion, and its capture set the wrapper's labels.
    assert dataset.success_labels().tolist() == [outcome["success"] for outcome in results["outcomes"]]
    # record's labels of the recorded states are the live wrapper's labels of the same states.
    for index, name in enumerate(("captured", "in_success")):
        live = [[label[index] for label in episode["labels"]] for episode in results["live"]]
        assert dataset.arrays[name].tolist() == live, name
    assert (out / "episode.png").stat().st_size > 0
