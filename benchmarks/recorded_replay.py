"""Recorded demonstrations replayed along their recorded robot paths, by the robot's armature.

A scene with ``motion.robot = "recorded"`` moves the robot along the path each roll-out was
recorded on, under a heavy armature and the forces of
:func:`~energy_margin.tasks.recorded_path.path_forces` (docs/howto/scenes.md). How heavy: this
benchmark writes the Jaco example's sweeps in robomimic's layout (``examples/robomimic/write_demos.py
--seed SEED``), records them with ``record --format robomimic --robot recorded`` (10 frames) and,
for each armature, replays each of the first ``--demos`` demonstrations from its first frame to its
end along its recorded path without perturbation, one command per control period as a tree's
propagation holds it. Reported per armature: how far the objects end from where the recording has
them (median and largest over the demonstrations of the largest object distance, m), how far the
robot's joints end from theirs (largest, rad or m), and in how many demonstrations the replay's
last state and the recording's agree on success.

    python benchmarks/recorded_replay.py --demonstration-seed 1 --work runs/recorded_replay_seed1 \\
        --out docs/figures/recorded_replay_seed1.json
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from energy_margin.data.dataset import Dataset, load_dataset
from energy_margin.runs.versions import engine_versions
from energy_margin.sim import make_model_simulator
from energy_margin.tasks.command import control_steps
from energy_margin.tasks.recorded_path import path_forces
from energy_margin.tasks.scene_task import SceneTask
from results_document import document_head, work_arguments, write_document
from robomimic_demos import EXAMPLES, FRAMES, _cli, _run

#: The armatures compared, kg m^2 or kg: a held robot's (1e8) down to 1e4.
ARMATURES = (1e8, 1e7, 1e6, 1e5, 1e4)


def recorded_set(work: Path, seed: int, demos: int) -> Dataset:
    """The demonstrations of ``seed`` recorded with ``--robot recorded`` under ``work`` (kept: a run resumes)."""
    if not (EXAMPLES / "jaco" / "jaco_scene.xml").exists():
        _run(EXAMPLES / "jaco" / "write_model.py")
    source, directory = work / "demos.hdf5", work / "recorded"
    if not source.exists():
        _run(EXAMPLES / "robomimic" / "write_demos.py", "--demos", demos, "--seed", seed, "--out", source)
    if not (directory / "dataset.json").exists():
        scene = EXAMPLES / "robomimic" / "jaco_demos.toml"
        _cli("record", "--format", "robomimic", source, "--scene", scene, "--robot", "recorded", "--frames", FRAMES,
             "--out", directory)  # fmt: skip
    return load_dataset(directory)


def replay(dataset: Dataset, trajectory: int, armature: float) -> dict[str, Any]:
    """Replay ``trajectory`` from its first frame to its last along its path under ``armature``."""
    task = dataset.task
    assert isinstance(task, SceneTask)
    arrays, loaded = dataset.arrays, task.loaded
    drive = arrays["drive"][trajectory]
    friction = float(arrays["friction"][trajectory])
    model, scene = task.compiled_model(friction, drive), task.build_scene(dataset.n_objects, friction)
    simulator = make_model_simulator(model, scene, object_joints=list(loaded.object_joints),
                                     robot_joints=list(loaded.robot_joints), coasting=True,
                                     robot_armature=armature)  # fmt: skip
    dt = task.config.timestep
    hold = control_steps(loaded.spec.motion.control_period, dt)
    assert hold is not None
    joints = len(loaded.robot_joints)
    start, end = float(arrays["frame_time"][trajectory, 0]), float(arrays["frame_time"][trajectory, -1])
    simulator.reset(dataset.frame(trajectory, 0))
    force = np.zeros(task.robot_dofs())
    steps = round((end - start) / dt)
    for step in range(0, steps, hold):
        force[:joints] = path_forces(drive[None], np.array([start + step * dt]), n_joints=joints, period=hold * dt,
                                     armature=armature)[0]  # fmt: skip
        simulator.set_robot_force(force)
        simulator.step(min(hold, steps - step))
    replayed, recorded = simulator.frame_state(), dataset.frame(trajectory, dataset.n_frames - 1)
    return {
        "object_distance_m": float(np.linalg.norm(replayed.object_pos - recorded.object_pos, axis=1).max()),
        "robot_deviation": float(np.abs(replayed.robot_q[:joints] - recorded.robot_q[:joints]).max()),
        "success_agrees": bool(task.is_successful(replayed) == task.is_successful(recorded)),
    }


def armature_rows(dataset: Dataset, demos: int, armatures: tuple[float, ...] = ARMATURES) -> list[dict[str, Any]]:
    """One row per armature over the first ``demos`` demonstrations."""
    rows = []
    for armature in armatures:
        found = [replay(dataset, trajectory, armature) for trajectory in range(demos)]
        distances = np.array([row["object_distance_m"] for row in found])
        rows.append({
            "armature": armature,
            "object_distance_median_m": float(np.median(distances)),
            "object_distance_max_m": float(distances.max()),
            "robot_deviation_max": float(max(row["robot_deviation"] for row in found)),
            "success_agrees": int(sum(row["success_agrees"] for row in found)),
            "demonstrations": demos,
        })  # fmt: skip
    return rows


def main() -> None:
    parser = work_arguments(__doc__, workers=False)
    parser.add_argument("--demonstration-seed", type=int, default=1, help="write_demos.py's --seed")
    parser.add_argument("--demos", type=int, default=20, help="demonstrations written and replayed")
    args = parser.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    dataset = recorded_set(args.work, args.demonstration_seed, args.demos)
    rows = armature_rows(dataset, min(args.demos, dataset.n_trajectories))
    print("| armature | objects off, median m | largest m | robot off, largest | success agrees |")
    print("|---|---|---|---|---|")
    for row in rows:
        print(f"| {row['armature']:.0e} | {row['object_distance_median_m']:.3f} | {row['object_distance_max_m']:.3f} | "
              f"{row['robot_deviation_max']:.4f} | {row['success_agrees']}/{row['demonstrations']} |")  # fmt: skip
    document = {
        **document_head("recorded_replay.py"),
        "versions": engine_versions(),
        "demonstration_seed": args.demonstration_seed,
        "frames": FRAMES,
        "rows": rows,
    }
    write_document(args.out, document)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
