"""Energy margins scored live in robosuite's PickPlace task, then ``record``, ``analyze`` and ``evaluate``.

    MUJOCO_GL=egl python examples/robosuite_pick_place/pick_place.py --episodes 40 --out runs/robosuite_pick_place

1. Makes ``PickPlace`` (Panda arm, robosuite's default ``OSC_POSE`` controller, 20 control steps
   per second, the milk, bread, cereal and can in ``bin1``), wraps it in robosuite's own
   ``GymWrapper`` and then in ``MarginWrapper``. The wrapper reads the MuJoCo model and data
   through ``env.sim`` (``sim.model._model``, ``sim.data._data``).
2. Writes the environment's compiled MJCF (``env.model.get_xml()``) as ``OUT/pick_place.xml`` and
   the scene file ``OUT/scene.toml`` beside it. The objects are the four ``*_main`` bodies, each
   with its free joint. Captured: at least one object's centre is within 6 cm of the gripper's
   grasp site. Success: at least one object's centre is inside ``bin2``.
3. Runs ``--episodes`` episodes of the scripted policy (``policy.py``; the target object and the
   noise are drawn from ``(seed, episode)``). The wrapper scores the reset and every
   ``--every``-th step within ``--budget`` seconds, the robot keeping its joint velocities during
   the tree's propagation (``--hold coasting``, the default: the controller's torques are not known
   ahead; ``--hold still`` holds it where it is). It records each
   episode as ``OUT/episodes/episode_NNN.npz``. In ``analyze`` the robot follows each episode's
   recorded joint path instead (the scene's ``robot = "recorded"``; ``--analysis hold`` does what
   ``--hold`` says there too).
4. Runs ``energy-margin record`` (its frames are the scored steps, checked),
   ``energy-margin analyze`` (``--expansions`` expansions per frame) and ``energy-margin evaluate``
   (capture AP at k-hat 0 and 2, success AP) on ``OUT/dataset``. It also writes the live scores
   into ``OUT/live`` (the same dataset) and evaluates them.
5. Draws ``OUT/pick_place.png`` with MuJoCo's renderer: three states of the first successful
   episode (else the first that lifts an object), each with its live scores and labels.

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
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import robosuite
from robosuite.wrappers import GymWrapper

from energy_margin.cli import main as cli
from energy_margin.evaluation.metrics import evaluate
from energy_margin.integrations.gymnasium import MarginWrapper

HERE = Path(__file__).resolve().parent
#: Control steps per second of the environment.
CONTROL_FREQ = 20
#: Captured: an object's centre within this distance of the grasp site, m.
CAPTURE_RADIUS = 0.06


def policy_module() -> Any:
    """``policy.py`` beside this file (loaded once, as ``robosuite_pick_place_policy``)."""
    name = "robosuite_pick_place_policy"
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


def make_env(env_seed: int, steps: int) -> Any:
    """PickPlace with the Panda arm, state observations only, one model for every episode."""
    return robosuite.make(
        "PickPlace",
        robots="Panda",
        has_renderer=False,
        has_offscreen_renderer=False,
        use_camera_obs=False,
        control_freq=CONTROL_FREQ,
        horizon=steps,
        hard_reset=False,
        seed=env_seed,
    )


def scene_text(
    mjcf: str, steps: int, objects: Sequence[str], grip_site: str, hold: str = "coasting", analysis: str = "recorded"
) -> str:
    """The scene file of this example: live, the robot does what ``hold`` says; in ``analyze``, ``analysis``."""
    robot = hold if analysis == "hold" else analysis
    bodies = ", ".join(f'"{name}_main"' for name in objects)
    return f"""# robosuite 1.5 PickPlace (Panda, OSC_POSE) with the scripted policy of policy.py.
schema_version = 1
mjcf = "{mjcf}"

[objects]
bodies = [{bodies}]
joints = "free"

# The controller's torques are not known ahead: {HOLD_COMMENTS[robot]}.
[motion]
duration = {steps / CONTROL_FREQ}
robot = "{robot}"

[perturbation]
linear_acceleration = [2.0, 2.0, 2.0]
angular_acceleration = [0.0, 0.0, 0.0]
max_duration = 0.1

# Both sets are taken at the analysed state (follow = false), as when the README's figures were
# measured; left out, a region on a body the robot moves would follow it (docs/howto/scenes.md).
# Captured: at least one object's centre within {CAPTURE_RADIUS} m of the grasp site (in the hand).
[capture]
follow = false
at_least = 1
region = {{ type = "distance", site = "{grip_site}", max = {CAPTURE_RADIUS} }}

# Success: at least one object's centre inside bin2 (0.4 m x 0.5 m, walls 0.1 m high).
[success]
follow = false
at_least = 1
region = {{ type = "box", body = "bin2", center = [0.0, 0.0, 0.06], half_size = [0.2, 0.25, 0.08] }}
"""


#: What the robot does during a tree's propagation (``--hold``), as the scene file's comment says it.
HOLD_COMMENTS = {
    "still": "the robot is held where each frame has it",
    "coasting": "the robot keeps each frame's joint velocities",
    "recorded": "the robot follows each episode's recorded joint path",
}
#: What the robot does during ``analyze``'s propagations (``--analysis``).
ANALYSIS_CHOICES = ("recorded", "hold")


def run_episode(wrapper: MarginWrapper, env: Any, steps: int, rng: np.random.Generator) -> dict[str, Any]:
    """One episode of the scripted policy; its live scores (one per scored step), labels and outcome."""
    policy = policy_module()
    model, data = env.sim.model._model, env.sim.data._data
    _, info = wrapper.reset()
    pick = policy.ScriptedPickPlace(env, rng)
    body = model.body(f"{pick.target}_main").id
    start = np.array(data.xpos[body])
    scores, labels, scored_steps, top = [info["energy_margin"]], [wrapper.labels()], [0], float(start[2])
    for step in range(1, steps + 1):
        _, _, _, _, info = wrapper.step(pick())
        top = max(top, float(data.xpos[body][2]))
        if "energy_margin" in info:
            scores.append(info["energy_margin"])
            labels.append(wrapper.labels())
            scored_steps.append(step)
    return {
        "target": pick.target,
        "scores": scores,
        "labels": [list(label) for label in labels],
        "steps": scored_steps,
        "lifted": top - float(start[2]) > 0.05,
        "moved": float(np.linalg.norm(data.xpos[body] - start)),
        "success": bool(labels[-1][1]),
    }


def render_picture(path: Path, model: mujoco.MjModel, rollout: Path, episode: dict[str, Any]) -> None:
    """Three scored states of ``episode`` side by side, rendered with MuJoCo, each with its scores and labels."""
    from PIL import Image, ImageDraw

    with np.load(rollout) as arrays:
        qpos = arrays["qpos"]
    data = mujoco.MjData(model)
    # The start, the first state in the hand (or the middle) and the end.
    frames = [0, len(episode["steps"]) // 2, len(episode["steps"]) - 1]
    captured = [index for index, label in enumerate(episode["labels"]) if label[0]]
    if captured:
        frames[1] = captured[len(captured) // 2]
    camera = mujoco.MjvCamera()
    camera.lookat[:] = [0.05, 0.0, 0.9]
    camera.distance, camera.azimuth, camera.elevation = 1.5, 180.0, -35.0
    panels = []
    with mujoco.Renderer(model, height=360, width=420) as renderer:
        for frame in frames:
            data.qpos[:] = qpos[episode["steps"][frame]]
            mujoco.mj_forward(model, data)
            renderer.update_scene(data, camera)
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
    parser.add_argument("--episodes", type=int, default=40)
    parser.add_argument("--steps", type=int, default=180, help="control steps per episode (20 per second)")
    parser.add_argument("--every", type=int, default=18, help="score the reset and every this many steps")
    parser.add_argument("--budget", type=float, default=0.05, help="wall-clock budget of one scoring call, s")
    parser.add_argument("--expansions", type=int, default=100, help="expansions per frame of `analyze`")
    parser.add_argument("--seed", type=int, default=0, help="seed of the policy's draws and of the trees")
    parser.add_argument("--env-seed", type=int, default=0, help="robosuite's seed (the object placements)")
    parser.add_argument("--out", type=Path, default=Path("runs/robosuite_pick_place"))
    parser.add_argument("--no-picture", action="store_true", help="skip the rendered picture")
    parser.add_argument(
        "--hold", choices=("coasting", "still"), default="coasting", help="the robot during a live tree's propagation"
    )
    parser.add_argument(
        "--analysis",
        choices=ANALYSIS_CHOICES,
        default="recorded",
        help="the robot during analyze's propagations: its episode's recorded joint path, or as --hold says",
    )
    args = parser.parse_args(argv)
    if args.episodes < 1 or args.every < 1 or args.steps % args.every:
        parser.error("--episodes must be >= 1 and --steps a multiple of --every")
    return args


def main(argv: Sequence[str] | None = None) -> dict[str, Any]:
    """Run the example (see the module docstring); returns what ``results.json`` holds."""
    args = parse_arguments(argv)
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    policy = policy_module()
    env = make_env(args.env_seed, args.steps)
    env.reset()
    (out / "pick_place.xml").write_text(env.model.get_xml(), encoding="utf-8")
    scene = out / "scene.toml"
    text = scene_text("pick_place.xml", args.steps, policy.OBJECTS, policy.GRIP_SITE, args.hold, args.analysis)
    scene.write_text(text, encoding="utf-8")
    wrapper = MarginWrapper(
        GymWrapper(env),
        scene=scene,
        every=args.every,
        budget_s=args.budget,
        hold=args.hold,
        record=True,
        seed=args.seed,
    )
    print(f"robosuite {robosuite.__version__}, MuJoCo {mujoco.__version__}; objects {wrapper.scorer.object_names}")
    episodes, files = [], []
    started = time.perf_counter()
    for index in range(args.episodes):
        episode = run_episode(wrapper, env, args.steps, np.random.default_rng([args.seed, index]))
        files.append(wrapper.save_episode(out / "episodes" / f"episode_{index:03d}.npz"))
        episodes.append(episode)
        ms = [score["ms"] for score in episode["scores"]]
        print(
            f"episode {index + 1}/{args.episodes}: {episode['target']:6s} lifted {episode['lifted']!s:5s} "
            f"success {episode['success']!s:5s} | {len(ms)} calls, {np.mean(ms):.1f} ms, "
            f"{np.mean([score['expansions'] for score in episode['scores']]):.1f} expansions per call",
            flush=True,
        )
    live_s = time.perf_counter() - started
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
        shown = next((i for i, e in enumerate(episodes) if e["success"]), None)
        shown = shown if shown is not None else next((i for i, e in enumerate(episodes) if e["lifted"]), 0)
        render_picture(out / "pick_place.png", env.sim.model._model, files[shown], episodes[shown])
    results = {
        "robosuite": robosuite.__version__,
        "mujoco": mujoco.__version__,
        "arguments": {key: str(value) for key, value in vars(args).items()},
        "timing": calls,
        "live_seconds": live_s,
        "lifted_rate": float(np.mean([episode["lifted"] for episode in episodes])),
        "success_rate": float(np.mean([episode["success"] for episode in episodes])),
        "episodes": [{key: value for key, value in e.items() if key != "scores"} for e in episodes],
        "scores": [episode["scores"] for episode in episodes],
        "evaluate": evaluations,
    }
    (out / "results.json").write_text(json.dumps(results, indent=1), encoding="utf-8")
    return results


if __name__ == "__main__":
    main()
