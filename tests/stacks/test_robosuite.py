"""The robosuite stack leg: PickPlace scored live by MarginWrapper, then record, analyze and evaluate.

Run as ``pip install . -r ci/stacks/robosuite.txt && pytest tests/stacks/test_robosuite.py``; the
main test leg has no robosuite and skips this file.
"""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path
from types import ModuleType

import numpy as np
from stack_legs import require

robosuite = require(
    "robosuite",
    leg="robosuite",
    reason="the robosuite stack leg only: pip install . -r ci/stacks/robosuite.txt (MuJoCo < 3.10)",
)

from robosuite.wrappers import GymWrapper  # noqa: E402

from energy_margin.data.dataset import load_dataset  # noqa: E402
from energy_margin.data.scores_file import load_scores  # noqa: E402
from energy_margin.integrations.gymnasium import MarginWrapper  # noqa: E402

FOLDER = Path(__file__).resolve().parents[2] / "examples" / "robosuite_pick_place"


def _module(name: str) -> ModuleType:
    spec = importlib.util.spec_from_file_location(f"robosuite_pick_place_{name}", FOLDER / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def test_scoring_leaves_the_environment_unchanged(tmp_path: Path) -> None:
    example = _module("pick_place")
    policy = example.policy_module()
    plain_env, scored_env = example.make_env(7, 60), example.make_env(7, 60)
    plain = GymWrapper(plain_env)
    scene = tmp_path / "scene.toml"
    (tmp_path / "pick_place.xml").write_text(plain_env.model.get_xml(), encoding="utf-8")
    scene.write_text(example.scene_text("pick_place.xml", 60, policy.OBJECTS, policy.GRIP_SITE), encoding="utf-8")
    scored = MarginWrapper(
        GymWrapper(scored_env), scene=scene, every=1, budget_s=None, max_expansions=3, hold="still", seed=0
    )
    observations = [plain.reset(), scored.reset()]
    np.testing.assert_array_equal(observations[0][0], observations[1][0])
    script = policy.ScriptedPickPlace(plain_env, np.random.default_rng(0), target="Can")
    scores = [observations[1][1]["energy_margin"]]
    for _ in range(40):
        action = script()
        first, second = plain.step(action), scored.step(action)
        np.testing.assert_array_equal(first[0], second[0])
        assert first[1:4] == second[1:4]
        scores.append(second[4]["energy_margin"])
    assert len(scores) == 41
    for score in scores:
        assert 0.0 <= score["capture_score"] <= 1.0 and 0.0 <= score["success_score"] <= 1.0
        assert score["expansions"] == 3 and score["nodes"] > 1
    # The scorer read the environment's state: its labels are those of the state the policy reached.
    grip = scored_env.sim.data._data.site_xpos[scored_env.sim.model._model.site(policy.GRIP_SITE).id]
    can = scored_env.sim.data._data.xpos[scored_env.sim.model._model.body("Can_main").id]
    assert scored.labels()[0] == bool(np.linalg.norm(grip - can) <= example.CAPTURE_RADIUS)


def test_example_end_to_end(tmp_path: Path) -> None:
    example = _module("pick_place")
    out = tmp_path / "run"
    arguments = ["--episodes", "3", "--every", "36", "--budget", "0.01", "--expansions", "5", "--out", str(out)]
    returned = example.main(arguments)
    results = json.loads((out / "results.json").read_text())
    assert results == json.loads(json.dumps(returned))
    assert results["timing"]["calls"] == 3 * 6
    assert results["timing"]["mean_expansions"] >= 1
    for episode in results["scores"]:
        for score in episode:
            assert 0.0 <= score["capture_score"] <= 1.0 and 0.0 <= score["success_score"] <= 1.0
            assert score["ms"] > 0
    # The scripted policy lifts an object in some episode; the labels take both values.
    assert any(episode["lifted"] for episode in results["episodes"])
    labels = np.array([episode["labels"] for episode in results["episodes"]])
    assert labels[..., 0].any() and not labels[..., 0].all()
    for folder in ("dataset", "live"):
        dataset = load_dataset(out / folder)
        assert dataset.arrays["frame_time"].shape == (3, 6)
        np.testing.assert_array_equal(dataset.arrays["captured"], labels[..., 0])
        scores = load_scores(out / folder)
        assert len(scores["trajectory"]) == 3 * 6
        assert np.all((scores["capture_score"] >= 0) & (scores["capture_score"] <= 1))
    # analyze follows each episode's recorded joint path (the Panda's 9 joints), kept in its drive.
    dataset = load_dataset(out / "dataset")
    assert dataset.task.loaded.spec.motion.robot == "recorded"
    assert dataset.arrays["drive"].shape == (3, 2 + 64 * (1 + 2 * 9))
    assert set(results["evaluate"]) == {"analyze", "live"}
    for evaluation in results["evaluate"].values():
        assert evaluation["verdict"] and 0.0 <= evaluation["capture_ap"] <= 1.0
    assert (out / "pick_place.png").stat().st_size > 10_000


def test_the_scene_follows_the_recorded_paths_in_analyze_as_the_hold_benchmark_writes_it() -> None:
    sys.path.insert(0, str(FOLDER.parents[1] / "benchmarks"))
    from robosuite_hold import recorded_scene

    example = _module("pick_place")
    policy = example.policy_module()
    held = example.scene_text("pick_place.xml", 180, policy.OBJECTS, policy.GRIP_SITE, "coasting", "hold")
    default = example.scene_text("pick_place.xml", 180, policy.OBJECTS, policy.GRIP_SITE)
    assert 'robot = "coasting"' in held and recorded_scene(held) == default
