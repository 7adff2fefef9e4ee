"""Is there a lambda without labels? AP at the hand-set, derived, calibrated and scale-free lambdas.

For the built-in ``pushing`` (5 objects) and ``scooping`` (3 objects) tasks and the example scenes
(run each example's ``write_model.py`` first; record/tabletop's roll-outs come from its
``simulate.py``), generates a small set per generation seed (11 chooses the rules' constants, 12
checks them; neither is a seed of the docs' other figures), grows every frame's tree once and keeps
its cost field (node costs and which nodes are captured and successful): a tree never reads lambda,
so every lambda below scores the very same trees. AP (capture k-hat 0 and 2, success on the first
half of the frames) is then measured at:

* ``hand_set``: the task's or scene file's lambda;
* ``derived``: what ``derive = true`` gives a scene file without ``lambda`` (its bounds kept);
* ``calibrated``: the best lambda of a grid by the mean of the three APs (in sample: an upper
  reference of what ``calibrate`` can reach);
* scale-free rules from each tree's own costs: ``median`` (lambda = kappa / median node cost),
  ``quantile`` (kappa / the q-quantile), ``ess`` (the lambda whose likelihood's effective sample
  size is a fraction f of the nodes), and ``dataset_median`` (one lambda per dataset: kappa / the
  median over all its trees' nodes).

    python benchmarks/lambda_rule.py --work runs/lambda_rule --out docs/figures/lambda_rule.json
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.analysis.frame import AnalyzerConfig, FrameAnalyzer, field_membership
from energy_margin.analysis.scores import likelihood, trajectory_success_score
from energy_margin.data.dataset import Dataset, load_dataset
from energy_margin.data.generate import generate_dataset
from energy_margin.data.record import record_dataset
from energy_margin.evaluation.metrics import average_precision
from energy_margin.tasks.scene_defaults import resolve_perturbation
from energy_margin.tasks.scene_model import load_scene

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
SCENES = {
    "pushing_scene": "pushing/pushing.toml",
    "fetch": "fetch/fetch.toml",
    "jaco": "jaco/jaco.toml",
    "panda_tray": "panda_tray/panda_tray.toml",
    "planar_manipulator": "planar_manipulator/planar_manipulator.toml",
    "gym_pusher": "gym_pusher/gym_pusher.toml",
    "tabletop": "record/tabletop.toml",
}
BUILTIN = {"pushing": 5, "scooping": 3}
GRID = tuple(float(value) for value in np.geomspace(0.1, 1e5, 49))
RULES: dict[str, tuple[float, ...]] = {
    "median": (0.5, 1.0, 2.0, 4.0, 8.0),
    "quantile10": (0.25, 0.5, 1.0, 2.0, 4.0),
    "ess": (0.05, 0.1, 0.2, 0.3, 0.5),
    "dataset_median": (0.5, 1.0, 2.0, 4.0, 8.0),
}
QUESTIONS = ("capture_ap", "capture_ap_window2", "success_ap_first_half")


def make_dataset(name: str, seed: int, out: Path, trajectories: int, frames: int) -> Dataset:
    """The set of ``name`` at generation seed ``seed`` (reused when ``out`` holds it)."""
    if (out / "dataset.json").exists():
        return load_dataset(out)
    if name in BUILTIN:
        return generate_dataset(
            name, n_objects=BUILTIN[name], n_trajectories=trajectories, n_frames=frames, seed=seed, out=out
        )
    scene = EXAMPLES / SCENES[name]
    if name == "tabletop":
        logs = out.parent / f"{out.name}-logs"
        command = [sys.executable, str(EXAMPLES / "record" / "simulate.py"), "--rollouts", str(trajectories)]
        subprocess.run([*command, "--seed", str(seed), "--out", str(logs)], check=True)
        return record_dataset(scene, sorted(logs.glob("run_*.npz")), n_frames=frames, out=out)
    return generate_dataset(
        "scene",
        n_objects=None,
        n_trajectories=trajectories,
        n_frames=frames,
        seed=seed,
        out=out,
        task_config={"scene_file": str(scene)},
    )


def derived_lambda(name: str) -> float | None:
    """What ``derive = true`` gives the scene file ``name`` without its ``lambda`` (its bounds kept)."""
    if name not in SCENES:
        return None
    loaded = load_scene(EXAMPLES / SCENES[name])
    settings = loaded.perturbation
    spec = dataclasses.replace(
        loaded.spec,
        likelihood_lambda=None,
        derive_perturbation=True,
        linear_acceleration=settings.linear_acceleration,
        angular_acceleration=settings.angular_acceleration,
        max_duration=settings.max_duration,
    )
    return resolve_perturbation(spec, loaded.model, loaded.object_bodies).likelihood_lambda


def grow_fields(dataset: Dataset, expansions: int, cache: Path) -> list[dict[str, np.ndarray]]:
    """Every frame's cost field (costs, captured, successful), trajectory-major; cached in ``cache``."""
    if cache.exists():
        arrays = np.load(cache)
        return [
            {key: arrays[f"{key}_{index}"] for key in ("costs", "captured", "successful")}
            for index in range(int(arrays["count"]))
        ]
    analyzer = FrameAnalyzer(dataset, AnalyzerConfig(expansions=expansions), seed=0)
    fields = []
    for index in range(dataset.n_trajectories * dataset.n_frames):
        _, field = analyzer.analyse(index)
        trajectory, frame = divmod(index, dataset.n_frames)
        captured, successful = field_membership(analyzer.task, dataset.frame(trajectory, frame), field)
        fields.append({"costs": np.asarray(field.costs, float), "captured": captured, "successful": successful})
    flat = {f"{key}_{i}": value for i, entry in enumerate(fields) for key, value in entry.items()}
    np.savez_compressed(cache, count=len(fields), **flat)
    return fields


def ess_lambda(costs: np.ndarray, fraction: float) -> float:
    """The lambda at which the likelihood's effective sample size is ``fraction`` of the nodes."""
    target = fraction * costs.size

    def ess(lam: float) -> float:
        weights = likelihood(costs, lam)
        return float(1.0 / np.sum(weights**2))

    low, high = 1e-6, 1e6
    if ess(high) >= target:
        return high
    for _ in range(60):
        middle = np.sqrt(low * high)
        low, high = (middle, high) if ess(middle) >= target else (low, middle)
    return float(np.sqrt(low * high))


def positive_costs(costs: np.ndarray) -> np.ndarray:
    """The costs of the nodes other than the root (cost 0), or every cost if none is above 0."""
    above = costs[costs > 0]
    return above if above.size else costs


def frame_lambdas(fields: list[dict[str, np.ndarray]], rule: str, constant: float) -> np.ndarray:
    """Each frame's lambda under ``rule`` with ``constant`` (kappa or fraction)."""
    if rule == "dataset_median":
        every = np.concatenate([positive_costs(entry["costs"]) for entry in fields])
        return np.full(len(fields), constant / max(float(np.median(every)), 1e-12))
    if rule == "ess":
        return np.array([ess_lambda(entry["costs"], constant) for entry in fields])
    quantile = 0.5 if rule == "median" else 0.1
    return np.array(
        [constant / max(float(np.quantile(positive_costs(entry["costs"]), quantile)), 1e-12) for entry in fields]
    )


def region_mass(entry: dict[str, np.ndarray], key: str, lam: float) -> float:
    """Likelihood mass of the nodes of ``entry`` in the set ``key`` at ``lam``."""
    return min(1.0, float(np.sum(likelihood(entry["costs"], lam)[entry[key]])))


def questions(dataset: Dataset, fields: list[dict[str, np.ndarray]], lams: np.ndarray) -> dict[str, float | None]:
    """AP per question with frame ``i`` scored at ``lams[i]``, and their mean as ``mean``."""
    shape = (dataset.n_trajectories, dataset.n_frames)
    capture = np.array([region_mass(e, "captured", lam) for e, lam in zip(fields, lams, strict=True)]).reshape(shape)
    success = np.array([region_mass(e, "successful", lam) for e, lam in zip(fields, lams, strict=True)]).reshape(shape)
    half = max(1, dataset.n_frames // 2)
    labels = dataset.success_labels()
    result: dict[str, float | None] = {
        "capture_ap": average_precision(dataset.capture_labels(0), capture),
        "capture_ap_window2": average_precision(dataset.capture_labels(2), capture),
        "success_ap_first_half": average_precision(
            labels, trajectory_success_score(success[:, :half], last=3, scheme="linear")
        ),
    }
    defined = [value for value in result.values() if value is not None]
    result["mean"] = float(np.mean(defined)) if defined else None
    return result


def measure(name: str, seed: int, args: argparse.Namespace) -> dict[str, Any]:
    """Every lambda's AP on the set of ``name`` at generation seed ``seed``."""
    out = args.work / f"{name}-seed{seed}"
    dataset = make_dataset(name, seed, out, args.trajectories, args.frames)
    fields = grow_fields(dataset, args.expansions, args.work / f"{name}-seed{seed}-fields.npz")
    count = len(fields)
    hand = float(dataset.task.config.likelihood_lambda)
    derived = derived_lambda(name)
    grid = {lam: questions(dataset, fields, np.full(count, lam)) for lam in GRID}
    best = max(GRID, key=lambda lam: (grid[lam]["mean"] or -1.0, -lam))
    rules = {
        f"{rule}:{constant:g}": questions(dataset, fields, frame_lambdas(fields, rule, constant))
        for rule, constants in RULES.items()
        for constant in constants
    }
    every = np.concatenate([positive_costs(entry["costs"]) for entry in fields])
    return {
        "trajectories": dataset.n_trajectories,
        "frames": dataset.n_frames,
        "nodes_mean": float(np.mean([entry["costs"].size for entry in fields])),
        "median_cost_J": float(np.median(every)),
        "hand_set": {"lambda": hand, **questions(dataset, fields, np.full(count, hand))},
        "derived": None
        if derived is None
        else {"lambda": derived, **questions(dataset, fields, np.full(count, derived))},
        "calibrated": {"lambda": best, **grid[best]},
        "grid": {f"{lam:.6g}": grid[lam]["mean"] for lam in GRID},
        "rules": rules,
    }


def gap(row: dict[str, Any], entry: dict[str, Any] | None) -> float | None:
    """How far below the calibrated mean AP ``entry`` is (``None``: no such lambda or no AP)."""
    if entry is None or entry["mean"] is None or row["calibrated"]["mean"] is None:
        return None
    return float(row["calibrated"]["mean"] - entry["mean"])


def worst(values: list[float | None]) -> float:
    """The largest of the defined gaps."""
    return max((value for value in values if value is not None), default=float("nan"))


def select(results: dict[str, Any], choose: str, check: str) -> dict[str, Any]:
    """Each rule's constant chosen on seed ``choose`` (smallest worst gap), and its gaps on ``check``."""
    selection: dict[str, Any] = {}
    for rule, constants in RULES.items():
        keys = [f"{rule}:{constant:g}" for constant in constants]
        chosen = min(
            keys, key=lambda key: worst([gap(rows[choose], rows[choose]["rules"][key]) for rows in results.values()])
        )
        check_gaps = {name: gap(rows[check], rows[check]["rules"][chosen]) for name, rows in results.items()}
        selection[rule] = {
            "chosen": chosen,
            "worst_gap_choose": worst([gap(rows[choose], rows[choose]["rules"][chosen]) for rows in results.values()]),
            "gaps_check": check_gaps,
            "worst_gap_check": worst(list(check_gaps.values())),
        }
    for setting in ("hand_set", "derived"):
        gaps = {name: gap(rows[check], rows[check][setting]) for name, rows in results.items()}
        selection[setting] = {"gaps_check": gaps, "worst_gap_check": worst(list(gaps.values()))}
    return selection


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", type=Path, default=Path("runs/lambda_rule"))
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--names", nargs="*", default=[*BUILTIN, *SCENES])
    parser.add_argument("--seeds", nargs="*", type=int, default=[11, 12])
    parser.add_argument("--trajectories", type=int, default=12)
    parser.add_argument("--frames", type=int, default=8)
    parser.add_argument("--expansions", type=int, default=80)
    args = parser.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    results: dict[str, Any] = {}
    for name in args.names:
        for seed in args.seeds:
            results.setdefault(name, {})[str(seed)] = row = measure(name, seed, args)
            print(name, seed, json.dumps({k: row[k] for k in ("hand_set", "derived", "calibrated")}), flush=True)
    if args.out is not None:
        document = {
            "settings": {
                "trajectories": args.trajectories,
                "frames": args.frames,
                "expansions": args.expansions,
                "seeds": args.seeds,
                "grid": list(GRID),
                "rules": {rule: list(values) for rule, values in RULES.items()},
                "questions": list(QUESTIONS),
            },
            "examples": results,
        }
        if len(args.seeds) == 2:
            document["selection"] = select(results, str(args.seeds[0]), str(args.seeds[1]))
        args.out.write_text(json.dumps(document, indent=1, sort_keys=True) + "\n")


if __name__ == "__main__":
    main()
