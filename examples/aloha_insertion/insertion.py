"""Energy margins scored live in gym-aloha's insertion task, then ``record``, ``analyze`` and ``evaluate``.

    MUJOCO_GL=egl python examples/aloha_insertion/insertion.py --episodes 12 --out runs/aloha_insertion

1. Makes ``gym.make("gym_aloha/AlohaInsertion-v0")`` (LeRobot's ALOHA simulation: two ViperX 300 S
   arms, a red peg and a blue socket, dm_control physics, 50 control steps per second; every
   observation is a 480 x 640 camera image) and wraps it in ``MarginWrapper``. The wrapper reads
   the MuJoCo model and data of the environment's dm_control ``Physics``
   (``env.unwrapped._env.physics``: ``physics.model.ptr``, ``physics.data.ptr``).
2. Writes the scene file ``OUT/scene.toml`` for gym-aloha's own model file
   (``gym_aloha/assets/bimanual_viperx_insertion.xml``, named by its absolute path). The objects
   are ``peg`` and ``socket``, each with its free joint. Captured: each object's centre within
   11 cm of a finger body of either arm (in a hand: a held object's centre is 8-9 cm from the
   finger bodies' origins). Success: both objects at least 10 cm above the table (lifted
   together, ready for the insertion).
3. Runs ``--episodes`` episodes of the scripted policy (``policy.py``; 150 steps, 3 s; the
   object poses come from gym-aloha's ``reset(seed)``, environment seed ``--env-seed`` + i, and
   the noise from ``(seed, episode)``). The wrapper scores the reset and every ``--every``-th
   step within ``--budget`` seconds; during the tree's propagation the arms hold their last joint
   targets (the position actuators' commands). Each episode is saved as
   ``OUT/episodes/episode_NNN.npz``.
4. Runs ``energy-margin record`` (its frames are the scored steps, checked),
   ``energy-margin analyze`` (``--expansions`` expansions per frame; the scene holds the robot
   still, since a recording's joint targets are not replayed) and ``energy-margin evaluate``
   (capture AP at k-hat 0 and 2, success AP) on ``OUT/dataset``. It also writes the live scores into ``OUT/live`` (the
   same dataset) and evaluates them.
5. Draws ``OUT/insertion.png`` with MuJoCo's renderer: three states of the first successful
   episode (else the first), each with its live scores and labels.

``OUT/results.json`` holds the time per call, the expansions, the outcomes and both evaluations.
A live tree stops at a wall-clock deadline, so its size depends on the machine's speed.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import shutil
import sys
import time
from collections.abc import Sequence
from importlib.metadata import version
from pathlib import Path
from typing import Any

import gym_aloha
import gymnasium
import mujoco
import numpy as np

from energy_margin.cli import main as cli
from energy_margin.evaluation.metrics import evaluate
from energy_margin.integrations.gymnasium import MarginWrapper

HERE = Path(__file__).resolve().parent
ENVIRONMENT = "gym_aloha/AlohaInsertion-v0"
#: gym-aloha's model file of the insertion task.
MODEL_FILE = Path(gym_aloha.__file__).resolve().parent / "assets" / "bimanual_viperx_insertion.xml"
#: Control steps per second of the environment.
CONTROL_FREQ = 50
#: Captured: an object's centre within this distance of a finger body, m.
CAPTURE_RADIUS = 0.11
#: Success: every object's centre at least this high above the table (z = 0), m.
LIFT_HEIGHT = 0.1


def policy_module() -> Any:
    """``policy.py`` beside this file (loaded once, as ``aloha_insertion_policy``)."""
    name = "aloha_insertion_policy"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, HERE / "policy.py")
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


def _stack_common() -> Any:
    """``examples/stack_common.py`` (loaded once, as ``stack_common``)."""
    if "stack_common" not in sys.modules:
        spec = importlib.util.spec_from_file_location("stack_common", HERE.parent / "stack_common.py")
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        sys.modules["stack_common"] = module
        spec.loader.exec_module(module)
    return sys.modules["stack_common"]


common = _stack_common()


def physics_of(env: Any) -> Any:
    """The dm_control ``Physics`` inside a gym-aloha environment."""
    return env.unwrapped._env.physics


def scene_text(mjcf: Path, steps: int) -> str:
    """The scene file of this example."""
    fingers = [f"vx300s_{arm}/{side}_finger_link" for arm in ("left", "right") for side in ("left", "right")]
    near = ",\n  ".join(f'{{ type = "distance", body = "{body}", max = {CAPTURE_RADIUS} }}' for body in fingers)
    return f"""# gym-aloha 0.1.5 AlohaInsertion-v0 with the scripted policy of policy.py.
schema_version = 1
mjcf = "{mjcf.as_posix()}"

[objects]
bodies = ["peg", "socket"]
joints = "free"

# The recorded joint targets are not replayed: the robot is held where each frame has it.
[motion]
duration = {steps / CONTROL_FREQ}
robot = "still"

[perturbation]
linear_acceleration = [2.0, 2.0, 2.0]
angular_acceleration = [0.0, 0.0, 0.0]
max_duration = 0.1

# Both sets are taken at the analysed state (follow = false), as when the README's figures were
# measured; left out, a region on a body the robot moves would follow it (docs/howto/scenes.md).
# Captured: each object's centre within {CAPTURE_RADIUS} m of a finger of either arm.
[capture]
follow = false
region = {{ type = "any", of = [
  {near},
] }}

# Success: both objects at least {LIFT_HEIGHT} m above the table.
[success]
follow = false
region = {{ type = "height", min = {LIFT_HEIGHT} }}
"""


def run_episode(wrapper: MarginWrapper, env_seed: int, steps: int, rng: np.random.Generator) -> dict[str, Any]:
    """One episode of the scripted policy; its live scores (one per scored step), labels and outcome."""
    policy = policy_module()
    physics = physics_of(wrapper)
    model, data = physics.model.ptr, physics.data.ptr
    _, info = wrapper.reset(seed=env_seed)
    script = policy.ScriptedInsertion(model, rng)
    bodies = [model.body(name).id for name in ("peg", "socket")]
    scores, labels, scored_steps = [info["energy_margin"]], [wrapper.labels()], [0]
    top = np.array([data.xpos[body][2] for body in bodies])
    reward = 0.0
    for step in range(1, steps + 1):
        _, reward, _, _, info = wrapper.step(script(data))
        top = np.maximum(top, [data.xpos[body][2] for body in bodies])
        if "energy_margin" in info:
            scores.append(info["energy_margin"])
            labels.append(wrapper.labels())
            scored_steps.append(step)
    return {
        "env_seed": env_seed,
        "scores": scores,
        "labels": [list(label) for label in labels],
        "steps": scored_steps,
        "peg_lifted": bool(top[0] > LIFT_HEIGHT),
        "socket_lifted": bool(top[1] > LIFT_HEIGHT),
        "reward": float(reward),
        "success": bool(labels[-1][1]),
    }


def render_picture(path: Path, model: mujoco.MjModel, rollout: Path, episode: dict[str, Any]) -> None:
    """Three scored states of ``episode`` side by side, rendered with MuJoCo, each with its scores and labels."""
    from PIL import Image, ImageDraw

    with np.load(rollout) as arrays:
        qpos = arrays["qpos"]
    data = mujoco.MjData(model)
    frames = [0, len(episode["steps"]) // 2, len(episode["steps"]) - 1]
    panels = []
    with mujoco.Renderer(model, height=360, width=480) as renderer:
        for frame in frames:
            data.qpos[:] = qpos[episode["steps"][frame]]
            mujoco.mj_forward(model, data)
            renderer.update_scene(data, camera="angle")
            image = Image.fromarray(renderer.render())
            draw = ImageDraw.Draw(image)
            score = episode["scores"][frame]
            label = episode["labels"][frame]
            text = (
                f"t = {episode['steps'][frame] / CONTROL_FREQ:.2f} s\n"
                f"capture {score['capture_score']:.2f} ({'in' if label[0] else 'out'})\n"
                f"success {score['success_score']:.2f} ({'in' if label[1] else 'out'})"
            )
            draw.rectangle([4, 4, 190, 62], fill=(255, 255, 255))
            draw.multiline_text((10, 8), text, fill=(0, 0, 0))
            panels.append(image)
    picture = Image.new("RGB", (sum(panel.width for panel in panels), panels[0].height), "white")
    for index, panel in enumerate(panels):
        picture.paste(panel, (index * panel.width, 0))
    picture.save(path)


def parse_arguments(argv: Sequence[str] | None) -> argparse.Namespace:
    """The command line."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--episodes", type=int, default=12)
    parser.add_argument("--steps", type=int, default=None, help="control steps per episode (default: the script's)")
    parser.add_argument("--every", type=int, default=15, help="score the reset and every this many steps")
    parser.add_argument("--budget", type=float, default=0.05, help="wall-clock budget of one scoring call, s")
    parser.add_argument("--expansions", type=int, default=100, help="expansions per frame of `analyze`")
    parser.add_argument("--seed", type=int, default=0, help="seed of the policy's noise and of the trees")
    parser.add_argument("--env-seed", type=int, default=0, help="gym-aloha's reset seed of episode 0")
    parser.add_argument("--out", type=Path, default=Path("runs/aloha_insertion"))
    parser.add_argument("--no-picture", action="store_true", help="skip the rendered picture")
    args = parser.parse_args(argv)
    if args.steps is None:
        args.steps = policy_module().STEPS
    if args.episodes < 1 or args.every < 1 or args.steps % args.every:
        parser.error("--episodes must be >= 1 and --steps a multiple of --every")
    return args


def main(argv: Sequence[str] | None = None) -> dict[str, Any]:
    """Run the example (see the module docstring); returns what ``results.json`` holds."""
    args = parse_arguments(argv)
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    scene = out / "scene.toml"
    scene.write_text(scene_text(MODEL_FILE, args.steps), encoding="utf-8")
    env = gymnasium.make(ENVIRONMENT)
    wrapper = MarginWrapper(env, scene=scene, every=args.every, budget_s=args.budget, record=True, seed=args.seed)
    print(f"gym-aloha {version('gym-aloha')}, MuJoCo {mujoco.__version__}; objects {wrapper.scorer.object_names}")
    episodes, files = [], []
    started = time.perf_counter()
    for index in range(args.episodes):
        rng = np.random.default_rng([args.seed, index])
        episode = run_episode(wrapper, args.env_seed + index, args.steps, rng)
        files.append(wrapper.save_episode(out / "episodes" / f"episode_{index:03d}.npz"))
        episodes.append(episode)
        ms = [score["ms"] for score in episode["scores"]]
        print(
            f"episode {index + 1}/{args.episodes} (env seed {episode['env_seed']}): peg lifted "
            f"{episode['peg_lifted']!s:5s} socket lifted {episode['socket_lifted']!s:5s} reward {episode['reward']:.0f}"
            f" | {len(ms)} calls, {np.mean(ms):.1f} ms, "
            f"{np.mean([score['expansions'] for score in episode['scores']]):.1f} expansions per call",
            flush=True,
        )
    live_s = time.perf_counter() - started
    env.close()
    calls = common.timing(episodes)
    print(
        f"live scoring: {calls['calls']} calls, {calls['mean_ms']:.1f} ms mean (p95 {calls['p95_ms']:.1f}, "
        f"max {calls['max_ms']:.1f}), {calls['mean_expansions']:.1f} expansions per call; episodes {live_s:.1f} s"
    )
    dataset = out / "dataset"
    frames = args.steps // args.every + 1
    arguments = ["--scene", str(scene), *map(str, files), "--frames", str(frames), "--out", str(dataset)]
    assert cli(["record", *arguments, "--overwrite"]) == 0
    common.check_frames(dataset, files, episodes)
    live = out / "live"
    shutil.rmtree(live, ignore_errors=True)
    shutil.copytree(dataset, live)
    common.write_live_scores(live, episodes)
    assert cli(["analyze", str(dataset), "--expansions", str(args.expansions), "--workers", "1", "--no-progress"]) == 0
    evaluations: dict[str, Any] = {}
    for name, directory in (("analyze", dataset), ("live", live)):
        print(f"\n== energy-margin evaluate {directory}  ({name} scores)")
        assert cli(["evaluate", str(directory)]) == 0
        evaluations[name] = common.summary(evaluate(directory).to_dict())
    if not args.no_picture:
        shown = next((i for i, episode in enumerate(episodes) if episode["success"]), 0)
        render_picture(out / "insertion.png", physics_of(wrapper).model.ptr, files[shown], episodes[shown])
    results = {
        "gym_aloha": version("gym-aloha"),
        "mujoco": mujoco.__version__,
        "arguments": {key: str(value) for key, value in vars(args).items()},
        "timing": calls,
        "live_seconds": live_s,
        "success_rate": float(np.mean([episode["success"] for episode in episodes])),
        "episodes": [{key: value for key, value in e.items() if key != "scores"} for e in episodes],
        "scores": [episode["scores"] for episode in episodes],
        "evaluate": evaluations,
    }
    (out / "results.json").write_text(json.dumps(results, indent=1), encoding="utf-8")
    return results


if __name__ == "__main__":
    main()
