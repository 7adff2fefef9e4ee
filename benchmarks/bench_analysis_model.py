"""Seconds per frame with the analysis model (``--analysis-model pruned``) against the full model.

Usage::

    python benchmarks/bench_analysis_model.py [--scenes examples/*/*.toml] [--trajectories 2]
        [--frames 4] [--expansions 300] [--seed 100] [--out docs/figures/analysis_model.json]

For each scene file, a small dataset is generated (``--trajectories`` x ``--frames``, generation
seed ``--seed``), then every frame is analysed twice in this one process, one model after the
other, frame by frame (so both sides see the same machine state): with the full model and with the
pruned one, the same seed and expansions. It prints per scene the geoms the pruned model kept
and dropped pairs for, the seconds per frame of each side (each frame's own tree timer: growth and
scoring), their ratio, and how many frames scored the same to the last bit. A scene whose robot
touches nothing but the objects and the world has nothing to drop apart from the robot's own pairs.
Examples whose model is written from another package's assets are skipped (one ``skip:`` line)
until their ``write_model.py`` has run (``python examples/NAME/write_model.py``).
Built-in tasks have one-body pushers and tools: nothing to drop (their pinned scores are unchanged).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
from pathlib import Path
from typing import Any

from energy_margin.analysis.frame import AnalyzerConfig, analyze_frame, frame_seeds
from energy_margin.data.dataset import load_dataset
from energy_margin.data.generate import generate_dataset
from energy_margin.errors import EnergyMarginError
from energy_margin.tasks import get_task

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_analysis import machine as describe_machine  # the machine line of the other benchmarks

__all__: list[str] = []

ROOT = Path(__file__).resolve().parents[1]
SCENES = sorted(str(path.relative_to(ROOT)) for path in ROOT.glob("examples/*/*.toml"))


def measure_scene(scene: str, args: argparse.Namespace, workdir: Path) -> dict[str, Any]:
    """Both models on every frame of a small generated set of ``scene``."""
    task = get_task("scene", {"scene_file": str(ROOT / scene)})
    out = workdir / Path(scene).stem
    generate_dataset(
        task, n_objects=None, n_trajectories=args.trajectories, n_frames=args.frames, seed=args.seed, out=out
    )
    dataset = load_dataset(out)
    seeds = frame_seeds(args.seed, dataset.n_trajectories * dataset.n_frames)
    times: dict[str, list[float]] = {"full": [], "pruned": []}
    same, report = 0, None
    for t in range(dataset.n_trajectories):
        friction, drive = float(dataset.arrays["friction"][t]), dataset.arrays["drive"][t]
        simulators = {
            model: dataset.task.make_simulator(dataset.n_objects, friction, drive) for model in ("full", "pruned")
        }
        for k in range(dataset.n_frames):
            seed = seeds[t * dataset.n_frames + k]
            scores = {}
            for model, simulator in simulators.items():
                config = AnalyzerConfig(expansions=args.expansions, analysis_model=model)
                result, _ = analyze_frame(
                    dataset.task,
                    dataset.frame(t, k),
                    friction=friction,
                    drive=drive,
                    seed=seed,
                    config=config,
                    simulator=simulator,
                    start_time=float(dataset.arrays["frame_time"][t, k]),
                )
                times[model].append(result.runtime_s)
                scores[model] = (result.capture_score, result.success_score)
            same += scores["full"] == scores["pruned"]
        report = simulators["pruned"].pruned_contacts
    assert report is not None  # every frame's pruned simulator was built and pruned
    full, pruned = statistics.mean(times["full"]), statistics.mean(times["pruned"])
    return {
        "scene": scene,
        "frames": len(times["full"]),
        "applied": bool(report.applied),
        "object_geoms": report.object_geoms,
        "robot_geoms": report.robot_geoms,
        "static_geoms": report.static_geoms,
        "robot_still": report.robot_still,
        "reason": report.reason,
        "full_s": full,
        "pruned_s": pruned,
        "speedup": full / pruned,
        "same_scores": same,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenes", nargs="+", default=SCENES)
    parser.add_argument("--trajectories", type=int, default=2)
    parser.add_argument("--frames", type=int, default=4)
    parser.add_argument("--expansions", type=int, default=300)
    parser.add_argument("--seed", type=int, default=100)
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    machine = f"{describe_machine()}; load average {os.getloadavg()[0]:.2f} before"
    print(f"machine: {machine}")
    rows = []
    with tempfile.TemporaryDirectory() as workdir:
        for scene in args.scenes:
            try:
                row = measure_scene(scene, args, Path(workdir))
            except EnergyMarginError as error:
                # Examples whose model comes from another package's assets (see their README).
                print(f"skip: {scene}: {error}", flush=True)
                continue
            rows.append(row)
            print(
                f"{row['scene']}: full {row['full_s']:.4f} s, pruned {row['pruned_s']:.4f} s, "
                f"{row['speedup']:.2f}x, same scores {row['same_scores']}/{row['frames']}",
                flush=True,
            )
    print()
    print(
        "| scene | robot geoms (pairs dropped) | robot still | full [s / frame] | pruned [s / frame] "
        "| ratio | same scores |"
    )
    print("|---|---:|---|---:|---:|---:|---:|")
    for row in rows:
        dropped = str(row["robot_geoms"]) if row["applied"] else f"0 ({row['reason']})"
        print(
            f"| {row['scene']} | {dropped} | {'yes' if row['robot_still'] else 'no'} | {row['full_s']:.4f} | "
            f"{row['pruned_s']:.4f} | {row['speedup']:.2f}x | {row['same_scores']} / {row['frames']} |"
        )
    if args.out:
        settings = {key: getattr(args, key) for key in ("trajectories", "frames", "expansions", "seed")}
        results = {"machine": machine, "settings": settings, "scenes": rows}
        args.out.write_text(json.dumps(results, indent=2) + "\n")
        print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
