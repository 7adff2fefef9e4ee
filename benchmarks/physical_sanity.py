"""Physical sanity of generated roll-outs: energy gained without work, warnings, refused draws.

For each built-in task and each example scene, runs the first draw of every trajectory of the
given generation seeds exactly as ``generate`` does and prints, per scene, the largest energy gain
beyond the work done (J and J per kg of moving mass), how many draws each test refuses, and what
``generate`` then does. Writes the table as JSON with ``--out``.

    python benchmarks/physical_sanity.py --seeds 200 201 --trajectories 10 --frames 10 \\
        --out docs/figures/physical_sanity.json
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from energy_margin.data.generate import RefusedDrawError, record_trajectory, roll_out, trajectory_rng
from energy_margin.data.physical import RolloutWatch, reason_kind
from energy_margin.runs.versions import engine_versions
from energy_margin.tasks import Task, get_task

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
SCENE_EXAMPLES = ("fetch", "gym_pusher", "jaco", "panda_tray", "planar_manipulator")


def _scene_task(name: str, folder: Path, overrides: dict[str, str]) -> Task:
    out = folder / name
    subprocess.run([sys.executable, str(EXAMPLES / name / "write_model.py"), "--out", str(out)], check=True)
    text = (EXAMPLES / name / f"{name}.toml").read_text(encoding="utf-8")
    scene = out / f"{name}.toml"
    scene.write_text(text, encoding="utf-8")
    for old, new in overrides.items():
        model = out / text.split('mjcf = "', 1)[1].split('"', 1)[0]
        model.write_text(model.read_text(encoding="utf-8").replace(old, new), encoding="utf-8")
    return get_task("scene", {"scene_file": str(scene)})


def _measure(task: Task, n_objects: int, seeds: list[int], trajectories: int, frames: int) -> dict[str, object]:
    gains, per_kg, refused = [], [], {}
    for seed in seeds:
        for index in range(trajectories):
            rng = trajectory_rng(seed, trajectories, index)
            trajectory = task.sample_trajectory(rng, n_objects)
            simulator = task.make_simulator(n_objects, trajectory.friction, trajectory.drive)
            simulator.reset(trajectory.initial)
            watch = RolloutWatch(simulator, task.frame_box)
            for _ in roll_out(task, trajectory, simulator, rng, task.frame_steps(frames), after_step=watch.after_step):
                watch.frame(simulator.frame_state())
            gain = watch.energy_gain() or 0.0
            gains.append(gain)
            per_kg.append(gain * 1.0 / max(watch.energy_limit(), 1e-12))
            try:
                record_trajectory(
                    task, n_objects, frames, trajectory_rng(seed, trajectories, index), check_overlaps=True
                )
            except RefusedDrawError as error:
                kind = reason_kind(str(error))
                refused[kind] = refused.get(kind, 0) + 1
    return {
        "roll_outs": len(gains),
        "max_gain_J": float(np.max(gains)),
        "max_gain_of_limit": float(np.max(per_kg)),
        "refused": refused,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[200, 201])
    parser.add_argument("--trajectories", type=int, default=10)
    parser.add_argument("--frames", type=int, default=10)
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    rows: dict[str, dict[str, object]] = {}
    with tempfile.TemporaryDirectory() as folder:
        scenes: list[tuple[str, Task, int]] = [
            ("pushing (10)", get_task("pushing"), 10),
            ("scooping (5)", get_task("scooping"), 5),
        ]
        for name in SCENE_EXAMPLES:
            task = _scene_task(name, Path(folder), {})
            scenes.append((name, task, task.fixed_objects or 1))
        for label, task, n_objects in scenes:
            rows[label] = _measure(task, n_objects, args.seeds, args.trajectories, args.frames)
            row = rows[label]
            print(
                f"{label:22s} roll-outs {row['roll_outs']:4d}  largest gain {row['max_gain_J']:10.4g} J "
                f"({row['max_gain_of_limit']:.3g} of the limit)  refused {row['refused']}",
                flush=True,
            )
    if args.out is not None:
        result = {
            "seeds": args.seeds,
            "trajectories": args.trajectories,
            "frames": args.frames,
            "versions": engine_versions("mujoco"),
            "scenes": rows,
        }
        args.out.write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
