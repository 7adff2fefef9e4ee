"""gymnasium-robotics' FetchPickAndPlace-v4 scored live by MarginWrapper, then recorded, analysed and evaluated.

A scripted pick-and-place policy (``policy.py``) with action noise of a different size in every
episode runs FetchPickAndPlace-v4 (MuJoCo <= 3.11: gymnasium-robotics 1.4.2 fails on later
versions), every episode's goal fixed at :data:`policy.GOAL`. ``MarginWrapper`` scores the reset
and every 5th step (11 states per episode of 50 steps) within ``--budget`` s and records the
episode. The script then writes the scene file, turns the recorded episodes into a dataset with
``energy-margin record`` (its 11 frames are the scored states), scores them offline with
``energy-margin analyze`` and prints ``energy-margin evaluate``'s AP table and verdict. It renders
the first successful and the first failed episode with MuJoCo's renderer (EGL without a display)
at four moments each into ``OUT/episode.png``.

Usage: ``python examples/fetch_pick_and_place/live_scores.py --episodes 50 --out runs/fetch_pick_and_place``
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import gymnasium
import gymnasium_robotics
import mujoco
import numpy as np

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


policy = _module(FOLDER / "policy.py", "fetch_pick_and_place_policy")
common = _module(FOLDER.parent / "stack_common.py", "stack_common")

ENVIRONMENT = "FetchPickAndPlace-v4"
#: Steps of an episode (the environment's own limit) and the scoring period.
STEPS, EVERY = 50, 5
#: Seconds per step (20 MuJoCo steps of 2 ms).
STEP_S = 0.04
#: Scored states per episode: the reset and every EVERY-th step.
SCORED = STEPS // EVERY + 1
#: The scene file writes follow = false in both sets: they are taken at the analysed state, as when the
#: README's figures were measured (left out, a region on the gripper would follow it, docs/howto/scenes.md).
#: Captured: the block's centre within 4 cm of the point between the fingertips (a held 5 cm block).
CAPTURE = {"type": "distance", "site": "robot0:grip", "max": 0.04}
#: Successful: the environment's own criterion, the block's centre within 5 cm of the goal.
SUCCESS = {"type": "distance", "site": "target0", "max": policy.SUCCESS_RADIUS}
#: Episode k's action noise (standard deviation) is drawn uniformly from [0, MAX_NOISE].
MAX_NOISE = 0.6
#: The moments of episode 0 in the picture (steps).
PICTURED = (0, 15, 30, 50)


def make_env() -> gymnasium.Env:
    """FetchPickAndPlace-v4 with the fixed goal, reset once so that the goal marker is in place."""
    gymnasium.register_envs(gymnasium_robotics)
    env = policy.FixedGoal(gymnasium.make(ENVIRONMENT))
    env.reset(seed=0)
    return env


def write_scene(env: gymnasium.Env, out: Path) -> tuple[Path, bool]:
    """``OUT/scene.toml`` and its model; whether that model is the one the environment runs.

    The environment edits its model in Python after loading its XML (the weld of the mocap body to
    the gripper gets the identity as its relative pose, the goal marker ``target0`` moves to the
    goal at reset, the offscreen buffer takes the render size), so ``energy-margin scene
    --from-gym`` saves the environment's compiled model itself (``starter.mjb``) and the scene
    names it.
    """
    starter = scene_from_environment(env, objects="object0", out=out / "starter.toml")
    same = starter.same_model
    perturbation = (
        "[perturbation]\nlinear_acceleration = [2.0, 2.0, 2.0]\nangular_acceleration = [0.0, 0.0, 0.0]\n"
        "max_duration = 0.1\n"
    )
    scene = out / "scene.toml"
    scene.write_text(
        "# FetchPickAndPlace-v4 with the goal at "
        f"{policy.GOAL.tolist()} (examples/fetch_pick_and_place/live_scores.py).\n"
        f'schema_version = 1\nmjcf = "{starter.model_file.name}"\n\n[objects]\nbodies = ["object0"]\n\n'
        f"[motion]\nduration = {STEPS * env.unwrapped.dt!r}\n\n{perturbation}\n"
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
    """One episode of the scripted policy; the live scores, the outcome and (with ``renderer``) pictures."""
    scripted = policy.ScriptedPickAndPlace(noise, rng)
    observation, info = wrapper.reset(seed=env_seed)
    scores, labels, steps, frames = [info["energy_margin"]], [wrapper.labels()], [0], {}
    if renderer is not None and 0 in PICTURED:
        frames[0] = renderer.draw(wrapper.unwrapped.data)
    for step in range(1, STEPS + 1):
        observation, _, _, _, info = wrapper.step(scripted(observation))
        if "energy_margin" in info:
            scores.append(info["energy_margin"])
            labels.append(wrapper.labels())
            steps.append(step)
        if renderer is not None and step in PICTURED:
            frames[step] = renderer.draw(wrapper.unwrapped.data)
    return {
        "env_seed": env_seed,
        "noise": noise,
        "success": bool(info["is_success"]),
        "phase": scripted.phase,
        "final_distance": float(np.linalg.norm(observation["achieved_goal"] - policy.GOAL)),
        "scores": scores,
        "labels": labels,
        "steps": steps,
        "frames": frames,
    }


def parse_arguments(argv: Sequence[str] | None) -> argparse.Namespace:
    """The command line."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--episodes", type=int, default=50)
    parser.add_argument("--out", type=Path, default=Path("runs/fetch_pick_and_place"))
    parser.add_argument("--budget", type=float, default=0.05, help="wall-clock budget of one live call, s")
    parser.add_argument("--expansions", type=int, default=300, help="expansions per frame of the offline analysis")
    parser.add_argument("--seed", type=int, default=0, help="seed of the trees, the noise sizes and the noise")
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
    env = make_env()
    scene, same_model = write_scene(env, out)
    print(f"scene {scene}; its model compiles to the environment's: {same_model}", flush=True)
    wrapper = MarginWrapper(env, scene=scene, every=EVERY, budget_s=args.budget, record=True, seed=args.seed)
    rng = np.random.default_rng(args.seed)
    noises = rng.uniform(0.0, MAX_NOISE, size=args.episodes)
    renderer = (
        None
        if args.no_picture
        else common.Canvas(
            env.unwrapped.model, 400, 300, lookat=(1.30, 0.78, 0.52), distance=1.0, azimuth=135.0, elevation=-20.0
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
            f"{'success' if episode['success'] else 'failure'} ({episode['phase']}, block "
            f"{episode['final_distance']:.3f} m from the goal); {len(ms)} live calls, mean {np.mean(ms):.1f} ms, "
            f"{np.mean([s['expansions'] for s in episode['scores']]):.0f} expansions",
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
        "mujoco": mujoco.__version__,
        "goal": policy.GOAL.tolist(),
        "same_model": same_model,
        "episodes": args.episodes,
        "budget_s": args.budget,
        "expansions": args.expansions,
        "seed": args.seed,
        "noises": noises.tolist(),
        "success_rate": float(np.mean([episode["success"] for episode in episodes])),
        "outcomes": [{k: e[k] for k in ("env_seed", "noise", "success", "phase", "final_distance")} for e in episodes],
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
