"""Early-success AP with and without success continuation (``analyze --continuation K``).

For each scene, two sets are generated (``energy-margin generate``, 10 frames per trajectory):
generation seed 11 to choose K and generation seed 12 to check the choice. Only the first five
frames of each trajectory are scored (early success reads no other): each frame's tree is grown
once, exactly as ``analyze`` grows it (the same per-frame seeds of :func:`frame_seeds` for analysis
seed 0, the same simulator reuse), and the continuations of every K are drawn from that tree, as
``analyze_frame`` with ``continuation=K`` does (checked on the first frame: the same score).

Early success as ``evaluate`` and the study define it: the trajectory's success score is the
weighted mean of the last 3 frame success scores (weights 1, 2, 3) among its first 3 (first 5)
frames, its AP scikit-learn's against the trajectory's success label. Baselines: ``chance`` (the
positive rate) and ``distance`` (the signed distance of the worst object to the success region).
Seconds per frame: tree growth plus the continuations, wall time on one process. ``paired``: each
K's AP minus the tree's own and minus the distance baseline's, with paired 95 % intervals over
1000 resamples of the trajectories (``evaluate``'s verdict statistics, resample seed 0).

    python benchmarks/success_continuation.py --out docs/figures/success_continuation.json
    python benchmarks/success_continuation.py --scenes gym_pusher scooping \
        --out docs/figures/success_continuation_more.json

K is chosen on generation seed 11 (:func:`choose`) and checked on seed 12.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.analysis.continuation import continued_success
from energy_margin.analysis.continuation_rule import AUTO_SAMPLES
from energy_margin.analysis.frame import AnalyzerConfig, analyze_frame, frame_seeds
from energy_margin.analysis.scores import trajectory_success_score
from energy_margin.data.dataset import Dataset, load_dataset
from energy_margin.evaluation.baselines import baseline_grids
from energy_margin.evaluation.bootstrap import Questions, paired_difference, score_questions
from energy_margin.evaluation.metrics import average_precision
from energy_margin.evaluation.verdict import word
from energy_margin.runs.versions import engine_versions

__all__: list[str] = []

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
#: Scene name -> (scene file, the example's ``write_model.py`` when its model is written on this machine).
SCENES = {
    "pushing_scene": ("pushing/pushing.toml", None),
    "panda_tray": ("panda_tray/panda_tray.toml", "panda_tray/write_model.py"),
    "gym_pusher": ("gym_pusher/gym_pusher.toml", None),
    "fetch": ("fetch/fetch.toml", "fetch/write_model.py"),
    "jaco": ("jaco/jaco.toml", "jaco/write_model.py"),
    "planar_manipulator": ("planar_manipulator/planar_manipulator.toml", "planar_manipulator/write_model.py"),
}
#: Built-in tasks: name -> ``generate`` options.
TASKS = {"pushing": ["--task", "pushing", "--objects", "10"], "scooping": ["--task", "scooping", "--objects", "5"]}
EARLY = {"first3": 3, "first5": 5}
LAST = 3
ANALYSIS_SEED = 0
#: Bootstrap resamples of the trajectories behind the paired intervals, and their seed.
RESAMPLES = 1000
RESAMPLE_SEED = 0


def _task_options(name: str, folder: Path) -> list[str]:
    """``generate``'s options: a built-in task, or a scene file beside its model (written if the example does)."""
    if name in TASKS:
        return TASKS[name]
    relative, writer = SCENES[name]
    source = EXAMPLES / relative
    if writer is None:
        return ["--scene", str(source)]
    out = folder / name
    subprocess.run([sys.executable, str(EXAMPLES / writer), "--out", str(out)], check=True, capture_output=True)
    shutil.copy(source, out / source.name)
    return ["--scene", str(out / source.name)]


def _generate(options: list[str], seed: int, trajectories: int, out: Path) -> Dataset:
    command = [sys.executable, "-m", "energy_margin", "generate", *options]
    command += ["--trajectories", str(trajectories), "--frames", "10", "--seed", str(seed), "--out", str(out)]
    subprocess.run(command, check=True, capture_output=True)
    return load_dataset(out)


def _scores(
    dataset: Dataset, expansions: int, ks: list[int], frames: int
) -> tuple[dict[int, np.ndarray], dict[int, float]]:
    """Success scores (T, frames) of the first ``frames`` frames per K (0: the tree's own) and seconds per frame."""
    task = dataset.task
    seeds = frame_seeds(ANALYSIS_SEED, dataset.n_trajectories * dataset.n_frames)
    config = AnalyzerConfig(expansions=expansions)
    lam = task.config.likelihood_lambda
    success = {k: np.zeros((dataset.n_trajectories, frames)) for k in [0, *ks]}
    seconds = dict.fromkeys([0, *ks], 0.0)
    for trajectory in range(dataset.n_trajectories):
        friction = float(dataset.arrays["friction"][trajectory])
        drive = dataset.arrays["drive"][trajectory]
        simulator = task.make_simulator(dataset.n_objects, friction, drive, config.engine)
        for frame_index in range(frames):
            index = trajectory * dataset.n_frames + frame_index
            frame = dataset.frame(trajectory, frame_index)
            start = float(dataset.arrays["frame_time"][trajectory, frame_index])
            started = time.perf_counter()
            scores, field = analyze_frame(
                task, frame, friction=friction, drive=drive, seed=seeds[index], config=config,
                start_time=start, simulator=simulator,
            )  # fmt: skip
            tree_s = time.perf_counter() - started
            success[0][trajectory, frame_index] = scores.success_score
            seconds[0] += tree_s
            for k in ks:
                tick = time.perf_counter()
                continued = continued_success(
                    simulator, task, frame, field, drive, lam=lam, samples=k, seed=seeds[index], start_time=start
                )
                seconds[k] += tree_s + time.perf_counter() - tick
                success[k][trajectory, frame_index] = continued.success_score
    count = dataset.n_trajectories * frames
    return success, {k: value / count for k, value in seconds.items()}


def _check_equivalence(dataset: Dataset, expansions: int, k: int, expected: float) -> None:
    """``analyze_frame`` with ``continuation=k`` gives the benchmark's score on the first frame."""
    drive = dataset.arrays["drive"][0]
    scores, _ = analyze_frame(
        dataset.task, dataset.frame(0, 0), friction=float(dataset.arrays["friction"][0]), drive=drive,
        seed=frame_seeds(ANALYSIS_SEED, dataset.n_trajectories * dataset.n_frames)[0],
        config=AnalyzerConfig(expansions=expansions, continuation=k),
        start_time=float(dataset.arrays["frame_time"][0, 0]),
    )  # fmt: skip
    if scores.success_score != expected:
        raise SystemExit(f"analyze_frame gives {scores.success_score}, the benchmark {expected}")


def _early_aps(labels: np.ndarray, grid: np.ndarray) -> dict[str, float | None]:
    """Early-success APs; with every frame of the trajectories scored, success from the last 3 too."""
    aps = {
        name: average_precision(labels, trajectory_success_score(grid[:, :frames], last=LAST))
        for name, frames in EARLY.items()
    }
    if grid.shape[1] > max(EARLY.values()):
        aps["last3"] = average_precision(labels, trajectory_success_score(grid, last=LAST))
    return aps


def paired(
    dataset: Dataset, success: dict[int, np.ndarray], distance: np.ndarray | None
) -> dict[str, dict[str, float | None]]:
    """Each K's early-success AP minus the tree's own (K = 0) and minus ``distance``'s, paired intervals.

    Args:
        dataset: the scored dataset (its success labels).
        success: success scores per K (0: the tree's own), each shape (T, frames scored).
        distance: the distance baseline's success scores, shape (T, frames scored), or ``None``.

    Returns:
        ``"continuation_K_minus_tree"``, ``"tree_minus_distance"``, ``"continuation_K_minus_distance"``
        -> question -> difference, with ``question_low`` and ``question_high``.
    """
    frames = success[0].shape[1]
    spans: dict[str, tuple[int | None, int | None]] = {name: (0, count) for name, count in EARLY.items()}
    if frames > max(EARLY.values()):
        spans["last3"] = (None, None)
    questions = Questions(dataset, LAST, capture_windows={}, success_spans=spans)
    drawn = np.random.default_rng(RESAMPLE_SEED).integers(0, len(success[0]), size=(RESAMPLES, len(success[0])))
    unused = np.zeros_like(success[0])  # no capture question is asked
    scored = {k: score_questions(questions, unused, grid, drawn) for k, grid in success.items()}
    ks = [k for k in success if k != 0]
    result = {f"continuation_{k}_minus_tree": paired_difference(scored[k], scored[0]) for k in ks}
    if distance is not None:
        baseline = score_questions(questions, unused, distance, drawn)
        result["tree_minus_distance"] = paired_difference(scored[0], baseline)
        for k in ks:
            result[f"continuation_{k}_minus_distance"] = paired_difference(scored[k], baseline)
    return result


def _measure(dataset: Dataset, expansions: int, ks: list[int], frames: int) -> dict[str, Any]:
    success, seconds = _scores(dataset, expansions, ks, frames)
    _check_equivalence(dataset, expansions, ks[-1], float(success[ks[-1]][0, 0]))
    labels = dataset.success_labels()
    methods: dict[str, Any] = {}
    for k in [0, *ks]:
        name = "tree" if k == 0 else f"continuation_{k}"
        grid = success[k]
        methods[name] = {
            **_early_aps(labels, grid),
            "seconds_per_frame": seconds[k],
            "frames_with_success_above_0": int(np.count_nonzero(grid > 0)),
        }
    # analyze's default (continuation_rule): AUTO_SAMPLES continuations per frame on MuJoCo.
    if AUTO_SAMPLES in ks:
        methods["auto"] = {**methods[f"continuation_{AUTO_SAMPLES}"], "continuation": AUTO_SAMPLES}
    methods["tree"]["unreached_share_all"] = float(np.mean(success[0][:, : -(-dataset.n_frames // 2)] == 0.0))
    questions = [name for name in (*EARLY, "last3") if name in methods["tree"]]
    baselines: dict[str, Any] = {"chance": dict.fromkeys(questions, float(np.mean(labels)))}
    grids = baseline_grids(dataset)
    distance = grids["distance"][1][:, :frames] if "distance" in grids else None
    if distance is not None:
        baselines["distance"] = _early_aps(labels, distance)
    return {
        "success_rate": float(np.mean(labels)),
        "methods": methods,
        "baselines": baselines,
        "paired": paired(dataset, success, distance),
    }


def _mean_aps(results: dict[str, Any], seeds: list[str]) -> dict[str, float]:
    """Mean early-success AP per K (0: the tree's own) over the scenes' sets of ``seeds``."""
    means: dict[str, float] = {}
    for k in [0, *results["ks"]]:
        name = "tree" if k == 0 else f"continuation_{k}"
        aps = [
            ap
            for scene in results["scenes"].values()
            for seed in seeds
            for ap in (scene[seed]["methods"][name][early] for early in EARLY)
            if ap is not None
        ]
        means[str(k)] = float(np.mean(aps)) if aps else float("nan")
    return means


def choose(results: dict[str, Any]) -> dict[str, Any]:
    """K of the best mean early-success AP over the scenes on the selection seed (ties: the smaller K).

    Each scene's AP of a K is the mean of its first-3 and first-5 APs (a scene whose labels hold a
    single class is left out); K = 0 is the tree's own success score. The check seeds are read only
    for the report: their mean APs, and each question where the chosen K is more than 0.01 below
    the tree's own score; ``time_ratio``: the chosen K's seconds per frame over the tree's, the
    smallest and largest over every set.
    """
    means = _mean_aps(results, [str(results["selection_seed"])])
    chosen = max(means, key=lambda k: (means[k], -int(k)))
    checks = [str(seed) for seed in results["check_seeds"]]
    behind, ratios = [], []
    if chosen != "0":
        for name, scene in results["scenes"].items():
            for seed, measured in scene.items():
                tree, continued = measured["methods"]["tree"], measured["methods"][f"continuation_{chosen}"]
                ratios.append(continued["seconds_per_frame"] / tree["seconds_per_frame"])
                for question in (*EARLY, "last3"):
                    before, after = tree.get(question), continued.get(question)
                    if seed in checks and before is not None and after is not None and after < before - 0.01:
                        behind.append(
                            {"scene": name, "seed": int(seed), "question": question, "difference": after - before}
                        )
    return {
        "rule": choose.__doc__.splitlines()[0] if choose.__doc__ else "",
        "mean_ap": means,
        "chosen_k": int(chosen),
        "check_mean_ap": _mean_aps(results, checks) if checks else {},
        "check_behind": behind,
        "time_ratio": {"min": min(ratios), "max": max(ratios)} if ratios else {},
    }


def rows(results: dict[str, Any]) -> list[dict[str, Any]]:
    """One flat record per scene and generation seed (for the docs' tables).

    APs and seconds per frame per method, and each paired difference with its interval and its
    word (``ahead``, ``level``, ``behind``: the interval above, around or below 0).
    """
    found = []
    for scene, seeds in results["scenes"].items():
        for seed, measured in seeds.items():
            record: dict[str, Any] = {
                "scene": scene,
                "seed": int(seed),
                "use": "choose" if seed == str(results["selection_seed"]) else "check",
            }
            for name, values in [*measured["methods"].items(), *measured["baselines"].items()]:
                for key, value in values.items():
                    if key in (*EARLY, "last3", "seconds_per_frame"):
                        record[f"{name}_{key}"] = value
            for name, values in measured.get("paired", {}).items():
                record.update({f"{name}_{key}": value for key, value in values.items()})
                for question in (*EARLY, "last3"):
                    if question in values:
                        found_word = word(values[question], values[f"{question}_low"], values[f"{question}_high"])
                        record[f"{name}_{question}_word"] = found_word
            found.append(record)
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument(
        "--scenes", nargs="+", default=["pushing_scene", "panda_tray", "pushing"], choices=[*SCENES, *TASKS]
    )
    parser.add_argument("--trajectories", type=int, default=20)
    parser.add_argument("--expansions", type=int, default=80)
    parser.add_argument("--ks", type=int, nargs="+", default=[8, 16])
    parser.add_argument("--seeds", type=int, nargs="+", default=[11, 12], help="choose on the first, check on the rest")
    parser.add_argument(
        "--choose-only", action="store_true", help="add the choice of K and the rows to an existing --out file"
    )
    parser.add_argument(
        "--all-frames", action="store_true", help="score every frame: success from the last 3 frames too (last3)"
    )
    args = parser.parse_args()
    results: dict[str, Any]
    if args.choose_only:
        results = json.loads(args.out.read_text())
        results["selection"] = choose(results)
        results["rows"] = rows(results)
        args.out.write_text(json.dumps(results, indent=2) + "\n")
        return
    results = {
        "command": "python benchmarks/success_continuation.py " + " ".join(sys.argv[1:]),
        "trajectories": args.trajectories,
        "frames": 10,
        "frames_scored": 10 if args.all_frames else max(EARLY.values()),
        "expansions": args.expansions,
        "analysis_seed": ANALYSIS_SEED,
        "ks": args.ks,
        "selection_seed": args.seeds[0],
        "check_seeds": args.seeds[1:],
        "versions": engine_versions("mujoco"),
        "scenes": {},
    }
    with tempfile.TemporaryDirectory() as folder:
        for name in args.scenes:
            options = _task_options(name, Path(folder))
            results["scenes"][name] = {}
            for seed in args.seeds:
                started = time.perf_counter()
                dataset = _generate(options, seed, args.trajectories, Path(folder) / f"{name}-{seed}")
                measured = _measure(dataset, args.expansions, args.ks, results["frames_scored"])
                measured["wall_s"] = time.perf_counter() - started
                results["scenes"][name][str(seed)] = measured
                print(name, seed, json.dumps(measured), flush=True)
    results["selection"] = choose(results)
    results["rows"] = rows(results)
    args.out.write_text(json.dumps(results, indent=2) + "\n")


if __name__ == "__main__":
    main()
