"""Reached states the trees reject, per frame, on the built-in tasks and every scene example at the defaults.

For each scene, generates a small set (generation seed 300 by default, used for nothing else),
analyses it at the default budget and prints the states rejected for leaving the task's state box
and for diverging, per frame (mean and largest) and as a share of the expansions.

    python benchmarks/tree_rejections.py --out docs/figures/tree_rejections.json
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.run import analyze
from energy_margin.data.generate import generate_dataset
from energy_margin.data.scores_file import load_scores, tree_rejections
from energy_margin.runs.versions import engine_versions

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
SCENE_EXAMPLES = ("fetch", "gym_pusher", "jaco", "panda_tray", "planar_manipulator")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=300)
    parser.add_argument("--trajectories", type=int, default=5)
    parser.add_argument("--frames", type=int, default=5)
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    rows = {}
    with tempfile.TemporaryDirectory() as folder:
        scenes: list[tuple[str, str, int | None, dict[str, str] | None]] = [
            ("pushing (10)", "pushing", 10, None),
            ("scooping (5)", "scooping", 5, None),
        ]
        for name in SCENE_EXAMPLES:
            out = Path(folder) / name
            subprocess.run(
                [sys.executable, str(EXAMPLES / name / "write_model.py"), "--out", str(out)],
                check=True,
                capture_output=True,
            )
            shutil.copy(EXAMPLES / name / f"{name}.toml", out / f"{name}.toml")
            scenes.append((name, "scene", None, {"scene_file": str(out / f"{name}.toml")}))
        for label, task, n_objects, config in scenes:
            path = Path(folder) / f"set-{label.split()[0]}"
            generate_dataset(
                task,
                n_objects=n_objects,
                n_trajectories=args.trajectories,
                n_frames=args.frames,
                seed=args.seed,
                out=path,
                task_config=config,
            )
            analyze(path, AnalyzerConfig(), seed=args.seed, progress=False)
            scores = load_scores(path)
            summary = tree_rejections(scores) or {}
            row = {
                **summary,
                "frames": int(scores["frame"].size),
                "rejected_max": int(scores["rejected"].max()),
                "diverged_max": int(scores["diverged"].max()),
                "expansions_per_frame": float(scores["iterations"].mean()),
            }
            rows[label] = row
            print(
                f"{label:20s} frames {row['frames']:3d}  rejected/frame {row['rejected_per_frame']:7.1f} "
                f"(max {row['rejected_max']:4d}, {100 * row['rejected_share']:5.1f}%)  diverged/frame "
                f"{row['diverged_per_frame']:6.2f} (max {row['diverged_max']:3d}, {100 * row['diverged_share']:5.2f}%)",
                flush=True,
            )
    if args.out is not None:
        result = {
            "seed": args.seed,
            "trajectories": args.trajectories,
            "frames": args.frames,
            "budget": "defaults (AnalyzerConfig())",
            "versions": engine_versions("mujoco"),
            "scenes": rows,
        }
        args.out.write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
