"""Energy margins scored live while a scripted policy plays Gymnasium's Pusher-v5, against the baselines.

    python examples/gymnasium_pusher/live_scores.py --episodes 50 --out runs/gym_pusher [--budget 0.05] [--seed 0]

1. Writes the starter scene of ``energy-margin scene --from-gym`` (``OUT/pusher.toml`` and the
   environment's model as ``OUT/pusher.xml``), then the scene file used here, ``OUT/scene.toml``:
   the puck ``object``; captured when the puck's centre is within 0.1 m of the fingertip body
   ``tips_arm`` (in contact with the fork's bar or about to be); successful when it is within
   0.1 m of the goal in the plane (the policy's success criterion); the perturbations of the
   starter file with lambda chosen in step 2.
2. Chooses lambda from ``--lambdas`` on calibration episodes whose environment seeds
   (``--calibration-seed`` + i) are disjoint from the reported ones (``--env-seed`` + i): the
   calibration episodes are recorded once, their scored states (reset and every 10th step) are
   scored once per lambda (the same state, held command and tree seeds as the wrapper would use;
   trees of ``--calibration-expansions`` expansions instead of a wall-clock budget, so that the
   choice does not depend on the machine's speed), and the lambda with the best mean of capture
   AP (k-hat = 2) and early success AP (success frames 3 within the first half of the frames)
   wins; a tie goes to the smaller lambda.
   Pusher's puck weighs 8e-6 kg but each of its slides has 0.04 kg of armature, which the
   perturbations' force bounds count (a scene's wrench bounds are (mass + armature) x acceleration).
3. Runs the reported episodes with ``MarginWrapper(env, scene=OUT/scene.toml, every=10,
   budget_s=BUDGET, record=True, seed=SEED)``: 11 scored states per episode (the reset and steps
   10, 20, ..., 100), each episode saved as ``OUT/episodes/episode_NNN.npz``.
4. Builds ``OUT/dataset`` from the roll-outs with ``record_dataset(..., n_frames=11)`` (its
   frames fall on the scored steps; checked), writes the live scores as ``OUT/dataset/scores.csv``
   (``expansions`` holds the tree's expansions, ``runtime_s`` the call's wall time; ``physics_s``
   is not measured by a live call and is written as 0), and prints the Average Precision of the
   energy margin, the current state, the distance to the region and chance for capture (k-hat 0
   and 2) and trajectory success from the first 3 and the first 5 scored states, with the
   positive rates and the wall time per call; ``OUT/results.json`` holds all of it and
   ``OUT/episode_scores.png`` shows both scores over one episode with its labels.

The AP is computed with the functions ``energy-margin evaluate`` uses (the same labels and
baselines), for questions ``evaluate`` does not ask (success from the first 3 or 5 scored states);
``evaluate`` itself is called on the dataset too and must give the same values on the questions
both ask (``evaluate_check`` in ``results.json``). The fork presses 4-6 cm into Pusher's soft puck
contact while pushing: a recorded set keeps such overlaps as warnings of ``check``.

Everything is deterministic given ``--seed`` (the environment seeds are fixed, the torque noise
of episode i is seeded by ``(seed, environment seed)``, the trees' seeds by ``seed``, and the
calibration's trees have a fixed size) except the effects of the wall-clock budget on the
reported scores: a live tree stops growing at its deadline, so its size, and with it the scores,
depend on how fast the machine runs it.
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
import mujoco
import numpy as np

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.scores import trajectory_success_score
from energy_margin.data.dataset import Dataset
from energy_margin.data.record import record_dataset
from energy_margin.data.scores_file import SCORES_FILE, format_row, header, load_scores
from energy_margin.errors import EnergyMarginError
from energy_margin.evaluation.baselines import distance_scores
from energy_margin.evaluation.metrics import average_precision, evaluate, score_grid
from energy_margin.integrations.gym_scene import scene_from_environment
from energy_margin.integrations.gymnasium import MarginWrapper
from energy_margin.integrations.live_model import LiveModelScorer, LiveOptions

HERE = Path(__file__).resolve().parent
ENVIRONMENT = "Pusher-v5"
#: Steps of one Pusher-v5 episode (its time limit).
STEPS = 100
#: The wrapper scores every this many steps (and the start state).
EVERY = 10
#: Scored states per episode: the reset and steps 10, 20, ..., 100.
SCORED = STEPS // EVERY + 1
#: Captured: the puck's centre within this distance of the fingertip body, m.
CAPTURE_RADIUS = 0.1
#: Success: the puck's centre within this planar distance of the goal, m.
SUCCESS_RADIUS = 0.1
#: Standard deviation of the policy's torque noise, N m.
NOISE = 0.2
LAMBDAS = (5.0, 1e4, 1e5, 1e6, 1e7)
METHODS = ("energy_margin", "current_state", "distance", "chance")
#: Rows of the table: key, question.
QUESTIONS = (
    ("capture_ap_k0", "capture AP, k-hat = 0"),
    ("capture_ap_k2", "capture AP, k-hat = 2"),
    ("success_ap_first3", "success AP, first 3 scored states (steps 0-20)"),
    ("success_ap_first5", "success AP, first 5 scored states (steps 0-40)"),
    ("success_ap_early3", "success AP, k-bar 3 of the first half (steps 20-40)"),
    ("success_ap_last3", "success AP, last 3 scored states (steps 80-100)"),
)


def scene_text(mjcf: str, likelihood_lambda: float | None) -> str:
    """The scene file of this example (``lambda`` left at its default when ``None``)."""
    if likelihood_lambda is None:
        lam = "# lambda: the default (the calibration sets it per candidate).\n"
    else:
        lam = f"# lambda: chosen on the calibration episodes (results.json).\nlambda = {float(likelihood_lambda)!r}\n"
    return f"""# Gymnasium's Pusher-v5 with the scripted policy of policy.py (see live_scores.py).
schema_version = 1
mjcf = "{mjcf}"

[objects]
bodies = ["object"]
joints = "upright"

[motion]
duration = {STEPS * 0.05}

# Both sets are taken at the analysed state (follow = false), as when the README's figures were
# measured; left out, a region on a body the robot moves would follow it (docs/howto/scenes.md).
# The puck only slides in the plane.
[perturbation]
linear_acceleration = [2.0, 2.0, 0.0]
angular_acceleration = [0.0, 0.0, 0.0]
max_duration = 0.1
{lam}
# Captured: the puck's centre within {CAPTURE_RADIUS} m of the fingertip (the fork's bar touches it).
[capture]
follow = false
region = {{ type = "distance", body = "tips_arm", max = {CAPTURE_RADIUS} }}

# Success: the puck's centre within {SUCCESS_RADIUS} m of the goal in the plane (the goal sits 4.8 cm lower).
[success]
follow = false
region = {{ type = "cylinder", body = "goal", center = [0.0, 0.0, 0.0], radius = {SUCCESS_RADIUS}, half_height = 0.2 }}
"""


def policy_class() -> Any:
    """The scripted policy of ``policy.py`` beside this file (loaded once, as ``gymnasium_pusher_policy``)."""
    name = "gymnasium_pusher_policy"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, HERE / "policy.py")
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name].ScriptedPusher


def planar_distance(model: mujoco.MjModel, data: mujoco.MjData) -> float:
    """The puck's distance to the goal in the plane, m."""
    return float(np.linalg.norm(data.xpos[model.body("object").id][:2] - data.xpos[model.body("goal").id][:2]))


def run_episode(wrapper: MarginWrapper, env_seed: int, seed: int, policy: Any, *, scored: bool) -> dict[str, Any]:
    """One episode of the scripted ``policy``; returns its scores (one dict per scored step) and outcome.

    The policy starts the episode with the noise generator of ``(seed, env_seed)``; ``scored``:
    whether the wrapper scores (then the start state is scored too).
    """
    model, data = wrapper.unwrapped.model, wrapper.unwrapped.data
    policy.reset(np.random.default_rng([seed, env_seed]))
    _, info = wrapper.reset(seed=env_seed)
    scores: list[dict[str, Any]] = []
    steps: list[int] = []
    if scored:
        # reset's info scores the start state; score it here where the wrapper does not (yet).
        scores.append(info["energy_margin"] if "energy_margin" in info else wrapper.scorer.score(data))
        steps.append(0)
    start = np.array(data.xpos[model.body("object").id][:2])
    for step in range(1, STEPS + 1):
        _, _, terminated, truncated, info = wrapper.step(policy(data))
        if "energy_margin" in info:
            scores.append(info["energy_margin"])
            steps.append(step)
        if terminated or (truncated and step < STEPS):
            raise EnergyMarginError(f"{ENVIRONMENT} ended at step {step}, before its {STEPS} steps")
    distance = planar_distance(model, data)
    return {
        "env_seed": env_seed,
        "scores": scores,
        "steps": steps,
        "final_distance": distance,
        "success": distance < SUCCESS_RADIUS,
        "puck_moved": float(np.linalg.norm(data.xpos[model.body("object").id][:2] - start)),
    }


def answers(dataset: Dataset, capture: np.ndarray, success: np.ndarray) -> dict[str, float | None]:
    """AP of one method's (T, K) capture and success scores for every question of :data:`QUESTIONS`."""
    labels = dataset.success_labels()
    half = max(1, dataset.n_frames // 2)

    def success_ap(columns: np.ndarray, last: int) -> float | None:
        return average_precision(labels, trajectory_success_score(columns, last=last, scheme="linear"))

    return {
        "capture_ap_k0": average_precision(dataset.capture_labels(0), capture),
        "capture_ap_k2": average_precision(dataset.capture_labels(2), capture),
        "success_ap_first3": success_ap(success[:, :3], 3),
        "success_ap_first5": success_ap(success[:, :5], 5),
        "success_ap_early3": success_ap(success[:, :half], 3),
        "success_ap_last3": success_ap(success, 3),
    }


def table(dataset: Dataset, capture: np.ndarray, success: np.ndarray) -> dict[str, dict[str, float | None]]:
    """``{question: {method: AP}}`` for the energy margin and the baselines of ``evaluate``."""
    current = (dataset.arrays["captured"].astype(float), dataset.arrays["in_success"].astype(float))
    zeros = np.zeros_like(capture)
    heuristic = distance_scores(dataset)
    per_method = {
        "energy_margin": answers(dataset, capture, success),
        "current_state": answers(dataset, *current),
        "distance": answers(dataset, *heuristic) if heuristic is not None else {},
        "chance": answers(dataset, zeros, zeros),
    }
    return {key: {method: per_method[method].get(key) for method in METHODS} for key, _ in QUESTIONS}


def positive_rates(dataset: Dataset) -> dict[str, float]:
    """Positive rates of the labels behind :func:`table`."""
    return {
        "capture_k0": float(dataset.capture_labels(0).mean()),
        "capture_k2": float(dataset.capture_labels(2).mean()),
        "success": float(dataset.success_labels().mean()),
    }


def evaluate_check(directory: Path, rows: dict[str, dict[str, float | None]]) -> dict[str, Any]:
    """Call ``evaluate`` on the dataset; whether it agrees with :func:`table`, or why it refused."""
    try:
        first = evaluate(directory, capture_window=0, success_frames=3).to_dict()
        fifth = evaluate(directory, capture_window=0, success_frames=5).to_dict()
    except EnergyMarginError as error:
        return {"evaluated": False, "refused": str(error)}
    pairs = {
        "capture_ap_k0": (first, "capture_ap"),
        "capture_ap_k2": (first, "capture_ap_window2"),
        "success_ap_early3": (first, "success_ap_first_half"),
        "success_ap_last3": (first, "success_ap"),
        "success_ap_first5": (fifth, "success_ap_first_half"),
    }
    names = {"energy_margin": None, "current_state": "current_state", "chance": "chance", "distance": "distance"}
    differences = []
    for key, (result, name) in pairs.items():
        for method, baseline in names.items():
            theirs = result[name] if baseline is None else result["baselines"].get(baseline, {}).get(name)
            ours = rows[key][method]
            if (theirs is None) != (ours is None) or (ours is not None and abs(ours - theirs) > 1e-9):
                differences.append(f"{key} {method}: {ours} here, {theirs} from evaluate")
    return {"evaluated": True, "agrees": not differences, "differences": differences}


def write_scores(directory: Path, episodes: list[dict[str, Any]]) -> None:
    """Write the live scores as the dataset's ``scores.csv`` (trajectory = episode, frame = scored state)."""
    lines = [header()]
    for trajectory, episode in enumerate(episodes):
        for frame, score in enumerate(episode["scores"]):
            row = {
                "trajectory": trajectory,
                "frame": frame,
                "capture_score": float(score["capture_score"]),
                "success_score": float(score["success_score"]),
                "tree_capture_score": float(score["tree_capture_score"]),
                "nodes": int(score["nodes"]),
                "expansions": int(score["expansions"]),
                "runtime_s": float(score["ms"]) / 1000.0,
                "physics_s": 0.0,
                "seed": int(score["seed"]),
            }
            lines.append(format_row(row) + "\n")
    (directory / SCORES_FILE).write_text("".join(lines), encoding="utf-8")


def check_frames(dataset: Dataset, files: list[Path], scored_steps: list[list[int]]) -> None:
    """Refuse a dataset whose frames are not the scored states (their recorded times must match)."""
    for trajectory, (path, steps) in enumerate(zip(files, scored_steps, strict=True)):
        with np.load(path) as rollout:
            expected = rollout["time"][steps]
        found = dataset.arrays["frame_time"][trajectory]
        if found.shape != expected.shape or not np.allclose(found, expected, rtol=0.0, atol=1e-9):
            raise EnergyMarginError(
                f"{path}: the dataset's frames (t = {np.round(found, 3).tolist()}) are not the scored steps "
                f"(t = {np.round(expected, 3).tolist()})"
            )


def calibrate(
    out: Path,
    env: gymnasium.Env,
    *,
    seeds: list[int],
    lambdas: Sequence[float],
    expansions: int,
    seed: int,
    noise: float,
) -> dict[str, Any]:
    """Record the calibration episodes, score their states once per lambda and pick the best lambda.

    The calibration trees grow ``expansions`` expansions each, without a wall-clock budget, so
    that the choice does not depend on the machine's speed.
    """
    folder = out / "calibration"
    folder.mkdir(parents=True, exist_ok=True)
    scene = out / "calibration.toml"
    scene.write_text(scene_text("pusher.xml", None), encoding="utf-8")
    recorder = MarginWrapper(env, scene=scene, every=0, record=True)
    policy = policy_class()(recorder.unwrapped.model, noise, np.random.default_rng(seed))
    files, outcomes = [], []
    for index, env_seed in enumerate(seeds):
        episode = run_episode(recorder, env_seed, seed, policy, scored=False)
        files.append(recorder.save_episode(folder / f"episode_{index:03d}.npz"))
        outcomes.append(episode["success"])
        print(
            f"calibration episode {index + 1}/{len(seeds)} (env seed {env_seed}): puck "
            f"{episode['final_distance']:.3f} m from the goal, {'success' if episode['success'] else 'failure'}",
            flush=True,
        )
    dataset = record_dataset(scene, files, n_frames=SCORED, out=folder / "dataset", overwrite=True)
    model = env.unwrapped.model
    state = mujoco.MjData(model)
    rows = [EVERY * frame for frame in range(SCORED)]
    results: dict[str, Any] = {}
    for lam in lambdas:
        config = AnalyzerConfig(likelihood_lambda=float(lam))
        options = LiveOptions(budget_s=None, max_expansions=expansions, seed=seed, config=config)
        scorer = LiveModelScorer(model, scene=scene, options=options)
        capture = np.zeros((len(files), SCORED))
        success = np.zeros_like(capture)
        for trajectory, path in enumerate(files):
            with np.load(path) as rollout:
                arrays = {name: rollout[name] for name in ("qpos", "qvel", "ctrl")}
            for frame, row in enumerate(rows):
                # The recorded state and held command, as the wrapper reads them from the live MjData.
                state.qpos[:], state.qvel[:], state.ctrl[:] = (
                    arrays["qpos"][row],
                    arrays["qvel"][row],
                    arrays["ctrl"][row],
                )
                score = scorer.score(state)
                capture[trajectory, frame], success[trajectory, frame] = score["capture_score"], score["success_score"]
        found = answers(dataset, capture, success)
        parts = [found["capture_ap_k2"], found["success_ap_early3"]]
        known = [value for value in parts if value is not None]
        mean = float(np.mean(known)) if known else None
        results[repr(float(lam))] = {
            "lambda": float(lam),
            "capture_ap_k2": found["capture_ap_k2"],
            "success_ap_early3": found["success_ap_early3"],
            "mean": mean,
        }
        print(
            f"lambda {float(lam):g}: capture AP (k-hat 2) {_cell(found['capture_ap_k2'])}, early success AP "
            f"{_cell(found['success_ap_early3'])}, mean {_cell(mean)}",
            flush=True,
        )
    scored = [entry for entry in results.values() if entry["mean"] is not None]
    # The best mean; a tie goes to the smaller lambda (max keeps the first of equals, lambdas ascending).
    ordered = sorted(scored, key=lambda entry: entry["lambda"])
    chosen = max(ordered, key=lambda entry: entry["mean"])["lambda"] if ordered else 5.0
    return {
        "seeds": seeds,
        "expansions": expansions,
        "success_rate": float(np.mean(outcomes)),
        "positive_rates": positive_rates(dataset),
        "by_lambda": results,
        "chosen": chosen,
        "rule": "best mean of capture AP (k-hat 2) and success AP (k-bar 3, first half); ties to the smaller lambda",
    }


def _cell(value: float | None) -> str:
    return "  n/a" if value is None else f"{value:5.3f}"


def format_table(rows: dict[str, dict[str, float | None]], rates: dict[str, float]) -> str:
    """The AP table as text."""
    widths = 52
    lines = [f"{'question':{widths}s} " + " ".join(f"{method:>13s}" for method in METHODS)]
    lines.append("-" * len(lines[0]))
    for key, question in QUESTIONS:
        lines.append(f"{question:{widths}s} " + " ".join(f"{_cell(rows[key][m]):>13s}" for m in METHODS))
    lines.append(
        f"positive rates: capture {rates['capture_k0']:.3f} (k-hat 0), {rates['capture_k2']:.3f} (k-hat 2), "
        f"success {rates['success']:.3f}"
    )
    return "\n".join(lines)


def plot_episode(path: Path, dataset: Dataset, episodes: list[dict[str, Any]], index: int) -> None:
    """Both live scores over episode ``index`` with its capture and success labels."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    times = dataset.arrays["frame_time"][index]
    scores = episodes[index]["scores"]
    captured = dataset.arrays["captured"][index]
    in_success = dataset.arrays["in_success"][index]
    figure, axes = plt.subplots(2, 1, figsize=(8, 5.5), sharex=True)
    for axis, key, labels, name in (
        (axes[0], "capture_score", captured, "capture"),
        (axes[1], "success_score", in_success, "success"),
    ):
        axis.plot(times, [score[key] for score in scores], "o-", color="tab:blue", label=f"{name} score (live)")
        axis.scatter(
            times[labels], np.full(int(labels.sum()), 1.08), marker="s", color="tab:green", label=f"in the {name} set"
        )
        axis.scatter(
            times[~labels], np.full(int((~labels).sum()), 1.08), marker="s", facecolors="none", edgecolors="tab:gray"
        )
        axis.set_ylim(-0.05, 1.15)
        axis.set_ylabel(f"{name} score")
        axis.legend(loc="center left", fontsize=8)
        axis.grid(alpha=0.3)
    episode = episodes[index]
    outcome = "success" if dataset.success_labels()[index] else "failure"
    axes[0].set_title(
        f"{ENVIRONMENT}, env seed {episode['env_seed']}: {outcome} (puck {episode['final_distance']:.3f} m "
        "from the goal at the end)\nsquares: label of the state (filled: in the set)",
        fontsize=9,
    )
    axes[1].set_xlabel("time in the episode, s")
    figure.tight_layout()
    figure.savefig(path, dpi=100)
    plt.close(figure)


def timing(episodes: list[dict[str, Any]], budget: float | None) -> dict[str, Any]:
    """Wall time per call, ms, and how often a call stopped at its budget and within 10 % of it."""
    calls = [score for episode in episodes for score in episode["scores"]]
    ms = np.array([score["ms"] for score in calls])
    by_budget = np.array([score["stopped_by"] == "budget" for score in calls])
    limit = budget * 1000.0 * 1.1 if budget is not None else float("inf")
    return {
        "calls": len(calls),
        "mean_ms": float(ms.mean()),
        "median_ms": float(np.median(ms)),
        "p95_ms": float(np.percentile(ms, 95)),
        "max_ms": float(ms.max()),
        "fraction_stopped_by_budget": float(by_budget.mean()),
        "fraction_budget_within_10_percent": float(np.mean(by_budget & (ms <= limit))),
        "mean_expansions": float(np.mean([score["expansions"] for score in calls])),
    }


def parse_arguments(argv: Sequence[str] | None) -> argparse.Namespace:
    """The command line."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--episodes", type=int, default=50, help="reported episodes")
    parser.add_argument("--out", type=Path, default=Path("runs/gym_pusher"))
    parser.add_argument("--budget", type=float, default=0.05, help="wall-clock budget of one tree, s")
    parser.add_argument("--seed", type=int, default=0, help="seed of the trees and of the torque noise")
    parser.add_argument("--noise", type=float, default=NOISE, help="torque noise of the policy, N m")
    parser.add_argument("--env-seed", type=int, default=1000, help="environment seed of reported episode 0")
    parser.add_argument("--calibration-seed", type=int, default=5000, help="environment seed of calibration episode 0")
    parser.add_argument("--calibration-episodes", type=int, default=15)
    parser.add_argument(
        "--calibration-expansions", type=int, default=125, help="expansions of a calibration tree (no budget)"
    )
    parser.add_argument("--lambdas", type=float, nargs="+", default=list(LAMBDAS), help="lambda candidates, 1/J")
    parser.add_argument(
        "--policy-continuation",
        type=int,
        default=0,
        metavar="K",
        help="continue the success score under the policy from K of each tree's states (0: the tree's own)",
    )
    args = parser.parse_args(argv)
    if args.policy_continuation < 0:
        parser.error("--policy-continuation must be at least 0")
    if min(args.episodes, args.calibration_episodes, args.calibration_expansions) < 1:
        parser.error("--episodes, --calibration-episodes and --calibration-expansions must be at least 1")
    if args.budget <= 0:
        parser.error("--budget must be > 0")
    return args


def main(argv: Sequence[str] | None = None) -> dict[str, Any]:
    """Run the example (see the module docstring); returns what ``results.json`` holds."""
    args = parse_arguments(argv)
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    env_seeds = [args.env_seed + i for i in range(args.episodes)]
    calibration_seeds = [args.calibration_seed + i for i in range(args.calibration_episodes)]
    if set(env_seeds) & set(calibration_seeds):
        raise SystemExit("the calibration and reported environment seeds overlap: change --calibration-seed")
    env = gymnasium.make(ENVIRONMENT)
    starter = scene_from_environment(env, objects="object", out=out / "pusher.toml")
    print(f"starter scene {starter.scene_file} (model {starter.model_file.name}, same model: {starter.same_model})")
    print(f"calibration: env seeds {calibration_seeds[0]}..{calibration_seeds[-1]}; lambdas {args.lambdas}")
    calibration = calibrate(
        out,
        env,
        seeds=calibration_seeds,
        lambdas=args.lambdas,
        expansions=args.calibration_expansions,
        seed=args.seed,
        noise=args.noise,
    )
    lam = calibration["chosen"]
    print(f"lambda = {lam:g} 1/J")
    scene = out / "scene.toml"
    scene.write_text(scene_text("pusher.xml", lam), encoding="utf-8")

    policy = policy_class()(env.unwrapped.model, args.noise, np.random.default_rng(args.seed))
    continued = {"policy": policy, "continuation": args.policy_continuation} if args.policy_continuation else {}
    wrapper = MarginWrapper(env, scene=scene, every=EVERY, budget_s=args.budget, record=True, seed=args.seed,
                            **continued)  # type: ignore[arg-type]  # fmt: skip
    episodes, files = [], []
    print(f"reported: env seeds {env_seeds[0]}..{env_seeds[-1]}")
    for index, env_seed in enumerate(env_seeds):
        episode = run_episode(wrapper, env_seed, args.seed, policy, scored=True)
        files.append(wrapper.save_episode(out / "episodes" / f"episode_{index:03d}.npz"))
        episodes.append(episode)
        ms = [score["ms"] for score in episode["scores"]]
        print(
            f"episode {index + 1}/{len(env_seeds)} (env seed {env_seed}): puck {episode['final_distance']:.3f} m from "
            f"the goal, {'success' if episode['success'] else 'failure'}; {len(ms)} calls, mean {np.mean(ms):.1f} ms",
            flush=True,
        )
    for episode in episodes:
        if episode["steps"] != [EVERY * frame for frame in range(SCORED)]:
            raise EnergyMarginError(f"env seed {episode['env_seed']}: scored steps {episode['steps']}")

    directory = out / "dataset"
    dataset = record_dataset(scene, files, n_frames=SCORED, out=directory, overwrite=True)
    check_frames(dataset, files, [episode["steps"] for episode in episodes])
    write_scores(directory, episodes)
    scores = load_scores(directory)
    rows = table(dataset, score_grid(dataset, scores, "capture_score"), score_grid(dataset, scores, "success_score"))
    rates = positive_rates(dataset)
    print(format_table(rows, rates))
    times = timing(episodes, args.budget)
    print(
        f"wall time per call: mean {times['mean_ms']:.1f} ms, median {times['median_ms']:.1f} ms, "
        f"p95 {times['p95_ms']:.1f} ms; stopped by the budget within 10 %: "
        f"{times['fraction_budget_within_10_percent']:.3f} of {times['calls']} calls"
    )
    check = evaluate_check(directory, rows)
    print("evaluate: " + (f"agrees: {check['agrees']}" if check["evaluated"] else f"refused ({check['refused']})"))

    labels = dataset.success_labels()
    changing = [i for i in range(len(episodes)) if labels[i] and not dataset.arrays["captured"][i].all()]
    shown = changing[0] if changing else 0
    plot_episode(out / "episode_scores.png", dataset, episodes, shown)
    results = {
        "environment": ENVIRONMENT,
        "episodes": args.episodes,
        "budget_s": args.budget,
        "policy_continuation": args.policy_continuation,
        "seed": args.seed,
        "noise": args.noise,
        "env_seeds": env_seeds,
        "calibration_seeds": calibration_seeds,
        "lambda": lam,
        "calibration": calibration,
        "scene": str(scene),
        "capture_radius": CAPTURE_RADIUS,
        "success_radius": SUCCESS_RADIUS,
        "scored_steps": episodes[0]["steps"],
        "frame_time": dataset.arrays["frame_time"][0].tolist(),
        "policy_success_rate": float(np.mean([episode["success"] for episode in episodes])),
        "puck_moved_rate": float(np.mean([episode["puck_moved"] > 0.01 for episode in episodes])),
        "table": rows,
        "questions": dict(QUESTIONS),
        "positive_rates": rates,
        "timing": times,
        "evaluate_check": check,
        "plotted_episode": shown,
        "final_distances": [episode["final_distance"] for episode in episodes],
    }
    (out / "results.json").write_text(json.dumps(results, indent=2) + "\n", encoding="utf-8")
    print(f"policy success rate {results['policy_success_rate']:.2f}; wrote {out / 'results.json'}")
    return results


if __name__ == "__main__":
    main()
