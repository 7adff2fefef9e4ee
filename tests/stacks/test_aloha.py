"""The gym-aloha stack leg: AlohaInsertion-v0 scored live by MarginWrapper, then record, analyze and evaluate.

Run as ``pip install . -r ci/stacks/aloha.txt && MUJOCO_GL=egl pytest tests/stacks/test_aloha.py``;
the main test leg has no gym-aloha and skips this file. Every step of the environment renders
three 480 x 640 camera images (about 0.3 s on a 2-core machine without a GPU), so the episodes
here are short.
"""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path
from types import ModuleType

import numpy as np
from stack_legs import require

gym_aloha = require(
    "gym_aloha", leg="aloha", reason="the gym-aloha stack leg only: pip install . -r ci/stacks/aloha.txt (MuJoCo < 3.9)"
)

import gymnasium  # noqa: E402

from energy_margin.data.dataset import load_dataset  # noqa: E402
from energy_margin.data.scores_file import load_scores  # noqa: E402
from energy_margin.integrations.gymnasium import MarginWrapper  # noqa: E402

FOLDER = Path(__file__).resolve().parents[2] / "examples" / "aloha_insertion"


def _module(name: str) -> ModuleType:
    spec = importlib.util.spec_from_file_location(f"aloha_insertion_{name}", FOLDER / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def test_scoring_leaves_the_environment_unchanged(tmp_path: Path) -> None:
    example = _module("insertion")
    policy = example.policy_module()
    scene = tmp_path / "scene.toml"
    scene.write_text(example.scene_text(example.MODEL_FILE, 30), encoding="utf-8")
    plain = gymnasium.make(example.ENVIRONMENT)
    scored = MarginWrapper(
        gymnasium.make(example.ENVIRONMENT), scene=scene, every=2, budget_s=None, max_expansions=3, seed=0
    )
    observations = [plain.reset(seed=3), scored.reset(seed=3)]
    np.testing.assert_array_equal(observations[0][0]["top"], observations[1][0]["top"])
    physics = example.physics_of(plain)
    script = policy.ScriptedInsertion(physics.model.ptr, np.random.default_rng(0))
    scores = [observations[1][1]["energy_margin"]]
    for _ in range(12):
        action = script(physics.data.ptr)
        first, second = plain.step(action), scored.step(action)
        np.testing.assert_array_equal(first[0]["top"], second[0]["top"])
        assert first[1:4] == second[1:4]
        if "energy_margin" in second[4]:
            scores.append(second[4]["energy_margin"])
    np.testing.assert_array_equal(physics.data.qpos, example.physics_of(scored).data.qpos)
    assert len(scores) == 7
    for score in scores:
        assert 0.0 <= score["capture_score"] <= 1.0 and 0.0 <= score["success_score"] <= 1.0
        assert score["expansions"] == 3 and score["nodes"] > 1


def test_example_end_to_end(tmp_path: Path) -> None:
    example = _module("insertion")
    out = tmp_path / "run"
    arguments = ["--episodes", "2", "--steps", "90", "--every", "15", "--budget", "0.01", "--expansions", "5"]
    returned = example.main([*arguments, "--out", str(out)])
    results = json.loads((out / "results.json").read_text())
    assert results == json.loads(json.dumps(returned))
    assert results["timing"]["calls"] == 2 * 7
    for episode in results["scores"]:
        for score in episode:
            assert 0.0 <= score["capture_score"] <= 1.0 and 0.0 <= score["success_score"] <= 1.0
            assert score["ms"] > 0 and score["expansions"] >= 1
    # The arms reach the objects: the capture labels take both values.
    labels = np.array([episode["labels"] for episode in results["episodes"]])
    assert labels[..., 0].any() and not labels[..., 0].all()
    for folder in ("dataset", "live"):
        dataset = load_dataset(out / folder)
        assert dataset.arrays["frame_time"].shape == (2, 7)
        np.testing.assert_allclose(dataset.arrays["frame_time"][0], np.arange(7) * 15 * 0.02, atol=1e-9)
        np.testing.assert_array_equal(dataset.arrays["captured"], labels[..., 0])
        assert len(load_scores(out / folder)["trajectory"]) == 2 * 7
    assert set(results["evaluate"]) == {"analyze", "live"}
    for evaluation in results["evaluate"].values():
        assert evaluation["verdict"] and 0.0 <= evaluation["capture_ap"] <= 1.0
    assert (out / "insertion.png").stat().st_size > 10_000
