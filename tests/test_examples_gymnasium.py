"""The Gymnasium Pusher example: the scripted policy moves the puck, and live_scores.py runs end to end."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

gymnasium = pytest.importorskip(
    "gymnasium", reason="the example needs Gymnasium (pip install 'energy-margin[gymnasium]')"
)

FOLDER = Path(__file__).resolve().parents[1] / "examples" / "gymnasium_pusher"


def _module(name: str) -> ModuleType:
    spec = importlib.util.spec_from_file_location(f"gymnasium_pusher_{name}", FOLDER / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def test_policy_moves_the_puck() -> None:
    policy = _module("policy")
    env = gymnasium.make("Pusher-v5")
    model, data = env.unwrapped.model, env.unwrapped.data
    puck = model.body("object").id
    moved = []
    for episode in range(3):
        env.reset(seed=1000 + episode)
        start = data.xpos[puck][:2].copy()
        pusher = policy.ScriptedPusher(model, 0.2, np.random.default_rng(episode))
        for _ in range(100):
            action = pusher(data)
            assert action.shape == (7,) and np.all(np.abs(action) <= 2.0)
            env.step(action)
        moved.append(float(np.linalg.norm(data.xpos[puck][:2] - start)))
    env.close()
    assert max(moved) > 0.01, moved


def test_live_scores_quick(tmp_path: Path) -> None:
    pytest.importorskip("matplotlib", reason="the example draws a picture (pip install 'energy-margin[plot]')")
    live_scores = _module("live_scores")
    out = tmp_path / "run"
    arguments = ["--episodes", "2", "--calibration-episodes", "2", "--calibration-expansions", "5"]
    arguments += ["--budget", "0.002", "--out", str(out)]
    returned = live_scores.main([*arguments, "--lambdas", "5", "1e6"])
    results = json.loads((out / "results.json").read_text())
    assert results == json.loads(json.dumps(returned))
    for key in (
        "lambda",
        "calibration",
        "env_seeds",
        "calibration_seeds",
        "table",
        "positive_rates",
        "timing",
        "policy_success_rate",
        "evaluate_check",
        "scored_steps",
        "frame_time",
    ):
        assert key in results, key
    assert results["lambda"] in (5.0, 1e6)
    assert not set(results["env_seeds"]) & set(results["calibration_seeds"])
    assert set(results["table"]) == {key for key, _ in live_scores.QUESTIONS}
    for row in results["table"].values():
        assert set(row) == set(live_scores.METHODS)
    assert results["timing"]["calls"] == 2 * 11
    # evaluate reads the recorded set (its overlaps are warnings) and gives the same AP.
    assert results["evaluate_check"]["evaluated"] and results["evaluate_check"]["agrees"], results["evaluate_check"]
    # The dataset's frames are the scored states: reset and every 10th step of 0.05 s.
    steps = list(range(0, 101, 10))
    assert results["scored_steps"] == steps
    from energy_margin.data.dataset import load_dataset
    from energy_margin.data.scores_file import load_scores

    dataset = load_dataset(out / "dataset")
    dt = gymnasium.make("Pusher-v5").unwrapped.dt
    for trajectory in range(2):
        with np.load(out / "episodes" / f"episode_{trajectory:03d}.npz") as rollout:
            recorded = rollout["time"][steps]
        np.testing.assert_allclose(dataset.arrays["frame_time"][trajectory], recorded, atol=1e-9)
        np.testing.assert_allclose(recorded, np.array(steps) * dt, atol=1e-9)
    scores = load_scores(out / "dataset")
    assert len(scores["trajectory"]) == 2 * 11
    assert (out / "scene.toml").read_text().count(f"lambda = {results['lambda']!r}") == 1
    assert (out / "episode_scores.png").stat().st_size > 0


def test_a_copy_of_the_policy_keeps_its_phase_and_draws_noise_of_its_own() -> None:
    import copy

    policy = _module("policy")
    env = gymnasium.make("Pusher-v5")
    model, data = env.unwrapped.model, env.unwrapped.data
    env.reset(seed=1003)
    pusher = policy.ScriptedPusher(model, 0.2, np.random.default_rng(4))
    for _ in range(12):
        env.step(pusher(data))
    untouched = copy.deepcopy(pusher.rng)
    copied = copy.deepcopy(pusher)
    assert copied.phase == pusher.phase and copied.model is pusher.model and copied.scratch is not pusher.scratch
    np.testing.assert_array_equal(copied.solution, pusher.solution)
    # The copy's noise is its own; the original draws on as if no copy had been made.
    ahead = untouched.normal(size=7)
    np.testing.assert_array_equal(pusher.rng.normal(size=7), ahead)
    assert not np.array_equal(copied.rng.normal(size=7), ahead)


def test_the_policy_s_continuation_leaves_the_episodes_as_they_were(tmp_path: Path) -> None:
    """The same episodes with the success continued under copies of the policy: the same outcomes."""
    pytest.importorskip("matplotlib", reason="the example draws a picture (pip install 'energy-margin[plot]')")
    live_scores = _module("live_scores")
    arguments = ["--episodes", "2", "--calibration-episodes", "2", "--calibration-expansions", "5"]
    arguments += ["--budget", "0.002", "--lambdas", "5"]
    plain = live_scores.main([*arguments, "--out", str(tmp_path / "plain")])
    continued = live_scores.main([*arguments, "--out", str(tmp_path / "continued"), "--policy-continuation", "2"])
    assert (plain["policy_continuation"], continued["policy_continuation"]) == (0, 2)
    assert continued["final_distances"] == plain["final_distances"]
    assert continued["timing"]["mean_ms"] > plain["timing"]["mean_ms"]  # the continuations run after the tree
