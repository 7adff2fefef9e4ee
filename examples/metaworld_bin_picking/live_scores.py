"""Meta-World's bin-picking-v3 scored live by MarginWrapper, then recorded, analysed and evaluated.

Meta-World 3.1.1 (which pins MuJoCo 3.3.0) registers ``Meta-World/MT1``; with
``env_name="bin-picking-v3"`` it is the Sawyer arm picking a cube out of one bin and placing it in
the other, the cube's start drawn from the benchmark's 50 tasks at every reset. Meta-World's own
scripted expert (``metaworld.policies.SawyerBinPickingV3Policy``) acts, with Gaussian action noise of
a different size in every episode. ``MarginWrapper`` scores the reset and every 25th step (21
states per episode of 500 steps) within ``--budget`` s and records the episode. The script then
writes the scene file, turns the recorded episodes into a dataset with ``energy-margin record``
(its 21 frames are the scored states), scores them offline with ``energy-margin analyze`` and prints
``energy-margin evaluate``'s AP table and verdict. It renders the first successful and the first
failed episode with MuJoCo's renderer (EGL without a display) at four moments each into
``OUT/episode.png``.

Usage: ``python examples/metaworld_bin_picking/live_scores.py --episodes 30 --out runs/metaworld_bin_picking``
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import sys
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import gymnasium
import metaworld  # noqa: F401 - registers the Meta-World/ environments
import mujoco
import numpy as np
from metaworld.policies import SawyerBinPickingV3Policy

from energy_margin.integrations.gym_scene import scene_from_environment
from energy_margin.integrations.gymnasium import MarginWrapper

FOLDER = Path(__file__).resolve().parent


def _module(path: Path, name: str) -> Any:
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


common = _module(FOLDER.parent / "stack_common.py", "stack_common")

ENVIRONMENT, TASK = "Meta-World/MT1", "bin-picking-v3"
#: Steps of an episode (Meta-World's max_path_length) and the scoring period.
STEPS, EVERY = 500, 25
#: Seconds per step (5 MuJoCo steps of 2.5 ms).
STEP_S = 0.0125
#: Scored states per episode: the reset and every EVERY-th step.
SCORED = STEPS // EVERY + 1
#: The cube's body: its free joint is on ``obj``, its geoms on the child body ``objA``.
OBJECT = "obj"
#: The scene file writes follow = false in both sets: they are taken at the analysed state, as when the
#: README's figures were measured (left out, a region on the gripper would follow it, docs/howto/scenes.md).
#: Captured: the cube's origin within 3 cm of the site between the fingers (a held cube is within 1.1 cm).
CAPTURE = {"type": "distance", "site": "endEffector", "max": 0.03}
#: Successful: Meta-World's own criterion, the cube within 5 cm of the goal bin's body origin.
SUCCESS = {"type": "distance", "body": "bin_goal", "max": 0.05}
#: Episode k's action noise (standard deviation; actions are in [-1, 1]) is drawn from [0, MAX_NOISE].
MAX_NOISE = 1.0
#: The moments of a pictured episode (steps).
PICTURED = (0, 75, 125, 500)


def make_env(seed: int = 0) -> gymnasium.Env:
    """bin-picking-v3 as ``gymnasium.make("Meta-World/MT1", env_name=...)`` makes it; Meta-World's warnings hidden."""
    # Meta-World's observation space has equal bounds in places; Gymnasium's checker says so at every make.
    warnings.filterwarnings("ignore", message=".*Box observation space maximum and minimum", category=UserWarning)
    warnings.filterwarnings("ignore", message=".*is not within the observation space", category=UserWarning)
    # The expert's gain (p=25) saturates the action: Meta-World says so once per process.
    warnings.filterwarnings("ignore", message="Constant.*may be too high", category=UserWarning)
    return gymnasium.make(ENVIRONMENT, env_name=TASK, seed=seed)


class NoisyExpert:
    """Meta-World's scripted expert with Gaussian action noise (the action clipped to [-1, 1])."""

    def __init__(self, noise: float, rng: np.random.Generator) -> None:
        self.expert = SawyerBinPickingV3Policy()
        self.noise = noise
        self.rng = rng

    def __call__(self, observation: np.ndarray) -> np.ndarray:
        """The expert's action plus noise."""
        action = self.expert.get_action(observation) + self.noise * self.rng.normal(size=4)
        return np.clip(action, -1.0, 1.0).astype(np.float32)


def write_scene(env: gymnasium.Env, out: Path) -> tuple[Path, bool]:
    """``OUT/scene.toml`` and its model; whether that model is the one the environment runs.

    Meta-World's ``reset_mocap_welds`` sets the weld of the mocap body to the hand (relative pose
    the identity, torque scale 5) in Python after loading its XML, so ``energy-margin scene
    --from-gym`` saves the environment's compiled model itself (``starter.mjb``) and the scene
    names it.
    """
    starter = scene_from_environment(env, objects=OBJECT, out=out / "starter.toml")
    same = starter.same_model
    scene = out / "scene.toml"
    scene.write_text(
        f"# Meta-World {TASK} (examples/metaworld_bin_picking/live_scores.py).\n"
        f'schema_version = 1\nmjcf = "{starter.model_file.name}"\n\n[objects]\nbodies = ["{OBJECT}"]\n\n'
        f"[motion]\nduration = {STEPS * STEP_S!r}\n\n"
        "[perturbation]\nlinear_acceleration = [2.0, 2.0, 2.0]\nangular_acceleration = [0.0, 0.0, 0.0]\n"
        "max_duration = 0.1\n\n"
        f"[capture]\nfollow = false\nregion = {_inline(CAPTURE)}\n\n"
        f"[success]\nfollow = false\nregion = {_inline(SUCCESS)}\n",
        encoding="utf-8",
    )
    return scene, same


def _inline(table: dict[str, Any]) -> str:
    """A region table as a TOML inline table."""
    return "{ " + ", ".join(f"{key} = {json.dumps(value)}" for key, value in table.items()) + " }"


def run_episode(
    wrapper: MarginWrapper, env_seed: int, noise: float, rng: np.random.Generator, renderer: Any = None
) -> dict[str, Any]:
    """One episode of the noisy expert; the live scores, the outcome and (with ``renderer``) pictures."""
    expert = NoisyExpert(noise, rng)
    observation, info = wrapper.reset(seed=env_seed)
    scores, labels, steps, frames = [info["energy_margin"]], [wrapper.labels()], [0], {}
    if renderer is not None and 0 in PICTURED:
        frames[0] = renderer.draw(wrapper.unwrapped.data)
    first_success = None
    for step in range(1, STEPS + 1):
        observation, _, terminated, truncated, info = wrapper.step(expert(observation))
        if "energy_margin" in info:
            scores.append(info["energy_margin"])
            labels.append(wrapper.labels())
            steps.append(step)
        if renderer is not None and step in PICTURED:
            frames[step] = renderer.draw(wrapper.unwrapped.data)
        if first_success is None and info["success"]:
            first_success = step
        if terminated or truncated:
            break
    return {
        "env_seed": env_seed,
        "noise": noise,
        "success": bool(info["success"]),
        "first_success": first_success,
        "final_distance": float(info["obj_to_target"]),
        "steps_run": step,
        "scores": scores,
        "labels": labels,
        "steps": steps,
        "frames": frames,
    }


def parse_arguments(argv: Sequence[str] | None) -> argparse.Namespace:
    """The command line."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--episodes", type=int, default=30)
    parser.add_argument("--out", type=Path, default=Path("runs/metaworld_bin_picking"))
    parser.add_argument("--budget", type=float, default=0.05, help="wall-clock budget of one live call, s")
    parser.add_argument("--expansions", type=int, default=100, help="expansions per frame of the offline analysis")
    parser.add_argument("--seed", type=int, default=0, help="seed of the trees, the task sampler and the noise")
    parser.add_argument("--env-seed", type=int, default=1000, help="environment seed of episode 0")
    parser.add_argument("--no-picture", action="store_true", help="render nothing")
    args = parser.parse_args(argv)
    if args.episodes < 1 or args.expansions < 1 or args.budget <= 0:
        parser.error("--episodes and --expansions must be at least 1 and --budget > 0")
    return args


def main(argv: Sequence[str] | None = None) -> dict[str, Any]:
    """Run the example (see the module docstring); returns what ``OUT/results.json`` holds."""
    args = parse_arguments(argv)
    out: Path = args.out
    (out / "episodes").mkdir(parents=True, exist_ok=True)
    env = make_env(args.seed)
    env.reset(seed=args.env_seed)
    scene, same_model = write_scene(env, out)
    print(f"scene {scene}; its model compiles to the environment's: {same_model}", flush=True)
    wrapper = MarginWrapper(env, scene=scene, every=EVERY, budget_s=args.budget, record=True, seed=args.seed)
    rng = np.random.default_rng(args.seed)
    noises = rng.uniform(0.0, MAX_NOISE, size=args.episodes)
    renderer = (
        None
        if args.no_picture
        else common.Canvas(
            env.unwrapped.model, 400, 300, lookat=(0.0, 0.68, 0.05), distance=0.9, azimuth=120.0, elevation=-30.0
        )
    )
    episodes, files, pictured = [], [], {}
    for index, noise in enumerate(noises):
        # Episodes are rendered until a success and a failure are in the picture.
        render = renderer if renderer is not None and len(pictured) < 2 else None
        episode = run_episode(wrapper, args.env_seed + index, float(noise), rng, render)
        if render is not None:
            pictured.setdefault(episode["success"], episode)
        files.append(str(wrapper.save_episode(out / "episodes" / f"episode_{index:03d}.npz")))
        episodes.append(episode)
        ms = [score["ms"] for score in episode["scores"]]
        print(
            f"episode {index} (env seed {episode['env_seed']}, noise {noise:.2f}): "
            f"{'success' if episode['success'] else 'failure'} (cube {episode['final_distance']:.3f} m from the "
            f"goal; first success at step {episode['first_success']}); {len(ms)} live calls, mean "
            f"{np.mean(ms):.1f} ms, {np.mean([s['expansions'] for s in episode['scores']]):.0f} expansions",
            flush=True,
        )
    if renderer is not None:
        common.save_episodes(out / "episode.png", [pictured[key] for key in (True, False) if key in pictured], STEP_S)
        renderer.close()
    times = common.timing(episodes)
    print(
        f"live calls: {times['calls']}, mean {times['mean_ms']:.1f} ms (median {times['median_ms']:.1f}, p95 "
        f"{times['p95_ms']:.1f}, max {times['max_ms']:.1f}), {times['mean_expansions']:.1f} expansions on average"
    )
    printed, evaluation = common.record_analyze_evaluate(
        scene, files, SCORED, out / "dataset", args.expansions, args.seed
    )
    results = {
        "environment": ENVIRONMENT,
        "task": TASK,
        "mujoco": mujoco.__version__,
        "same_model": same_model,
        "episodes": args.episodes,
        "budget_s": args.budget,
        "expansions": args.expansions,
        "seed": args.seed,
        "noises": noises.tolist(),
        "success_rate": float(np.mean([episode["success"] for episode in episodes])),
        "outcomes": [
            {k: e[k] for k in ("env_seed", "noise", "success", "first_success", "final_distance", "steps_run")}
            for e in episodes
        ],
        "timing": times,
        "live": [
            {"steps": e["steps"], "scores": e["scores"], "labels": [list(label) for label in e["labels"]]}
            for e in episodes
        ],
        "evaluate": evaluation,
        "evaluate_text": printed,
        "picture": None if args.no_picture else str(out / "episode.png"),
    }
    (out / "results.json").write_text(json.dumps(results, indent=2) + "\n", encoding="utf-8")
    print(f"policy success rate {results['success_rate']:.2f}; wrote {out / 'results.json'}")
    return results


if __name__ == "__main__":
    main()
