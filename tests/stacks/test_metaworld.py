"""Meta-World 3.1.1's bin-picking-v3 scored live by MarginWrapper (examples/metaworld_bin_picking).

The stack leg: ``pip install . -r ci/stacks/metaworld.txt`` (Meta-World pins MuJoCo 3.3.0), then
``ENERGY_MARGIN_STACK_LEG=metaworld pytest tests/stacks/test_metaworld.py``.
"""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest
from stack_legs import mujoco_version, require

LEG = "metaworld"
require("metaworld", leg=LEG, reason="the Meta-World stack is not installed (pip install . -r ci/stacks/metaworld.txt)")
pytest.importorskip("PIL", reason="the example draws its picture with Pillow (a dependency of Meta-World's imageio)")

from energy_margin.data.dataset import load_dataset  # noqa: E402
from energy_margin.integrations.gymnasium import MarginWrapper  # noqa: E402

FOLDER = Path(__file__).resolve().parents[2] / "examples" / "metaworld_bin_picking"


def _module(name: str) -> ModuleType:
    spec = importlib.util.spec_from_file_location(f"metaworld_bin_picking_{name}", FOLDER / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


live_scores = _module("live_scores")


def _episode(env, seed: int, noise: float, steps: int) -> tuple[list, list, list]:
    """Observations, rewards and infos of the noisy expert's first ``steps`` steps."""
    expert = live_scores.NoisyExpert(noise, np.random.default_rng(seed))
    observation, info = env.reset(seed=seed)
    observations, rewards, infos = [observation], [], [info]
    for _ in range(steps):
        observation, reward, _, _, info = env.step(expert(observation))
        observations.append(observation)
        rewards.append(reward)
        infos.append(info)
    return observations, rewards, infos


def test_wrapper_scores_without_changing_the_environment(tmp_path: Path) -> None:
    steps = 120  # the expert has lifted the cube by step 75
    # Meta-World draws the task (the cube's start) at reset from the generator as the last episode left it:
    # both environments reset once before the compared episode.
    plain_env = live_scores.make_env(3)
    plain_env.reset(seed=7)
    plain = _episode(plain_env, 7, 0.1, steps)
    env = live_scores.make_env(3)
    env.reset(seed=7)
    scene, same_model = live_scores.write_scene(env, tmp_path)
    assert same_model  # the scene's model compiles to the model the environment runs
    wrapper = MarginWrapper(env, scene=scene, every=10, budget_s=None, max_expansions=4, record=True, seed=0)
    wrapped = _episode(wrapper, 7, 0.1, steps)
    for before, after in zip(plain[0], wrapped[0], strict=True):
        np.testing.assert_array_equal(before, after)
    assert plain[1] == wrapped[1]
    margins = [info["energy_margin"] for info in wrapped[2] if "energy_margin" in info]
    assert len(margins) == steps // 10 + 1
    for margin in margins:
        assert 0.0 <= margin["capture_score"] <= 1.0 and 0.0 <= margin["success_score"] <= 1.0
        assert 1 <= margin["expansions"] <= 4 and margin["ms"] > 0
    assert margins[0]["capture_score"] == 0.0  # the cube starts in the other bin, away from the hand
    assert wrapper.labels()[0]  # the expert holds the cube at step 120
    with np.load(wrapper.save_episode(tmp_path / "episode.npz")) as rollout:
        assert rollout["qpos"].shape == (steps + 1, env.unwrapped.model.nq)
        np.testing.assert_array_equal(rollout["qpos"][-1], env.unwrapped.data.qpos)


def test_example_end_to_end(tmp_path: Path) -> None:
    out = tmp_path / "run"
    returned = live_scores.main(["--episodes", "2", "--out", str(out), "--expansions", "3", "--budget", "0.01"])
    results = json.loads((out / "results.json").read_text())
    assert results == json.loads(json.dumps(returned))
    assert results["same_model"] and results["mujoco"] == ".".join(map(str, mujoco_version()))
    assert results["timing"]["calls"] == 2 * live_scores.SCORED and results["timing"]["mean_expansions"] >= 1
    for episode in results["live"]:
        assert episode["steps"] == list(range(0, live_scores.STEPS + 1, live_scores.EVERY))
        for score in episode["scores"]:
            assert 0.0 <= score["capture_score"] <= 1.0 and 0.0 <= score["success_score"] <= 1.0
    # record -> analyze -> evaluate wrote their files, and the evaluation has its verdict.
    dataset = load_dataset(out / "dataset")
    for name in ("dataset.json", "scores.csv"):
        assert (out / "dataset" / name).stat().st_size > 0
    evaluation = results["evaluate"]
    assert evaluation["n_trajectories"] == 2 and evaluation["n_frames"] == 2 * live_scores.SCORED
    assert set(evaluation["verdict"]) >= {"capture_ap", "success_ap"}
    assert "verdict" in results["evaluate_text"]
    # The scene's success set is Meta-World's own criterion at the last step.
    assert dataset.success_labels().tolist() == [outcome["success"] for outcome in results["outcomes"]]
    # record's labels of the recorded states are the live wrapper's labels of the same states.
    for index, name in enumerate(("captured", "in_success")):
        live = [[label[index] for label in episode["labels"]] for episode in results["live"]]
        assert dataset.arrays[name].tolist() == live, name
    assert (out / "episode.png").stat().st_size > 0
