r"""Write a demonstration file in robomimic's layout from the Kinova Jaco example (dm_control's arm, four boxes).

robomimic (and robosuite's demonstration collection) store one HDF5 file: a group ``data`` with
one subgroup per demonstration, ``data/demo_N``, holding ``states`` (N, 1 + nq + nv: time, qpos,
qvel of every step, robosuite's flattened MuJoCo state), ``actions`` (N, A) and the attribute
``model_file`` (the model's XML); ``data`` carries ``total`` and ``env_args`` (JSON). This script
writes such a file from the Jaco example of ``examples/jaco`` (run its ``write_model.py`` first):
each demonstration starts the four boxes where the example's scene file draws them (seed
``--seed``, demonstration i from the i-th child of ``numpy.random.SeedSequence(seed)``) and runs the
scene's paddle sweep at the drawn speed (time scale 0.9–1.1), with the model's own friction and
masses (one model for all demonstrations, as a recording session has). ``states`` are taken every
``--every`` physics steps; ``actions`` are the actuators' controls at those steps; ``model_file``
is the compiled scene written back with ``MjSpec.to_xml`` (the four box copies in place, the
meshes by the absolute paths where pip put dm_control).

    python examples/jaco/write_model.py
    python examples/robomimic/write_demos.py --demos 50 --out runs/jaco_demos.hdf5
    energy-margin record --format robomimic runs/jaco_demos.hdf5 --scene examples/robomimic/jaco_demos.toml \
        --frames 10 --out runs/jaco_demos
"""

from __future__ import annotations

import argparse
import copy
import json
from pathlib import Path

import numpy as np

from energy_margin.sim.mujoco_model import MujocoModelSimulator
from energy_margin.tasks import get_task
from energy_margin.tasks.base import command_robot
from energy_margin.tasks.scene_model import compile_spec
from energy_margin.tasks.scene_task import SceneTask

HERE = Path(__file__).resolve().parent
JACO_SCENE = HERE.parent / "jaco" / "jaco.toml"


def demonstration(
    task: SceneTask, seed: np.random.SeedSequence, every: int, *, nominal_speed: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """One sweep: states (n, 1 + nq + nv) and actions (n, nu) every ``every`` physics steps.

    ``nominal_speed``: run the motion at its declared speed (time scale 1) instead of the drawn one.
    """
    loaded = task.loaded
    trajectory = task.sample_trajectory(np.random.default_rng(seed), loaded.n_objects)
    speed = 1.0 if nominal_speed else trajectory.drive[0]
    drive = np.array([speed, 1.0])  # the model's own masses
    simulator = MujocoModelSimulator(
        copy.copy(loaded.model),
        task.build_scene(loaded.n_objects, task.default_friction(), drive),
        object_joints=list(loaded.object_joints),
        robot_joints=list(loaded.robot_joints),
    )
    simulator.reset(trajectory.initial)
    data = simulator.data
    steps = round(task.config.duration / simulator.timestep)
    states, actions = [], []
    for step in range(steps + 1):
        command_robot(task, simulator, drive, step * simulator.timestep, None)
        if step % every == 0:
            states.append(np.concatenate([[data.time], data.qpos, data.qvel]))
            actions.append(np.array(data.ctrl))
        if step < steps:
            simulator.step(1)
    return np.array(states), np.array(actions)


def main() -> None:
    """Write the file."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--demos", type=int, default=50)
    parser.add_argument("--every", type=int, default=5, help="physics steps between stored states")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--scene", type=Path, default=JACO_SCENE, help="the Jaco example's scene file")
    parser.add_argument("--out", type=Path, required=True, help="the .hdf5 file to write")
    parser.add_argument(
        "--nominal-speed", action="store_true", help="run every sweep at the declared speed (time scale 1)"
    )
    parser.add_argument(
        "--npz", type=Path, help="also write each demonstration as an .npz roll-out (time, qpos, qvel, ctrl) here"
    )
    args = parser.parse_args()
    import h5py

    task = get_task("scene", {"scene_file": str(args.scene.resolve())})
    assert isinstance(task, SceneTask)
    model_spec, _ = compile_spec(task.loaded.spec)
    xml = model_spec.to_xml()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    seeds = np.random.SeedSequence(args.seed).spawn(args.demos)
    with h5py.File(args.out, "w") as handle:
        group = handle.create_group("data")
        total = 0
        for index, seed in enumerate(seeds):
            states, actions = demonstration(task, seed, args.every, nominal_speed=args.nominal_speed)
            if args.npz is not None:
                args.npz.mkdir(parents=True, exist_ok=True)
                nq = task.loaded.model.nq
                np.savez(
                    args.npz / f"demo_{index:03d}.npz",
                    time=states[:, 0],
                    qpos=states[:, 1 : 1 + nq],
                    qvel=states[:, 1 + nq :],
                    ctrl=actions,
                )
            demo = group.create_group(f"demo_{index}")
            demo.create_dataset("states", data=states)
            demo.create_dataset("actions", data=actions)
            demo.attrs["model_file"] = xml
            demo.attrs["num_samples"] = len(states)
            total += len(states)
            print(f"demo_{index}: {len(states)} states", flush=True)
        group.attrs["total"] = total
        group.attrs["env_args"] = json.dumps(
            {
                "env_name": "JacoSweep",
                "type": 1,
                "env_kwargs": {"control_freq": 1.0 / (args.every * task.config.timestep)},
            }
        )
    print(f"wrote {args.out}: {args.demos} demonstrations, {total} states")


if __name__ == "__main__":
    main()
