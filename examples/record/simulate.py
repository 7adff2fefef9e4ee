"""A user's own MuJoCo loop: a feedback controller pushes three boxes and logs each roll-out.

Nothing here uses energy-margin. Each roll-out starts the boxes at random, then a controller
steers the pusher: its forward target follows a ramp (0.25 m/s after 0.2 s) and its sideways
target follows the boxes' centroid (gain 0.8), i.e. it reacts to where the boxes are. Every step
is logged in MuJoCo's own layout: time, qpos, qvel and ctrl, one .npz per roll-out.

    python examples/record/simulate.py --rollouts 20 --out examples/record/logs
"""

from __future__ import annotations

import argparse
from pathlib import Path

import mujoco
import numpy as np

HERE = Path(__file__).resolve().parent
DURATION = 2.0  # s
SPEED = 0.25  # m/s
START_DELAY = 0.2  # s
STEER_GAIN = 0.8


def forward_target(time: float) -> float:
    """Nominal y target of the pusher, m (the scene file declares the same ramp)."""
    return SPEED * max(time - START_DELAY, 0.0)


def rollout(model: mujoco.MjModel, rng: np.random.Generator) -> dict[str, np.ndarray]:
    data = mujoco.MjData(model)
    boxes = [model.jnt_qposadr[model.body(f"box_{i}").jntadr[0]] for i in (1, 2, 3)]
    for address in boxes:
        data.qpos[address : address + 2] += rng.uniform([-0.012, -0.03], [0.012, 0.03])
        yaw = rng.uniform(-0.5, 0.5)
        data.qpos[address + 3 : address + 7] = [np.cos(yaw / 2), 0, 0, np.sin(yaw / 2)]
    log: dict[str, list[np.ndarray]] = {"time": [], "qpos": [], "qvel": [], "ctrl": []}
    steps = round(DURATION / model.opt.timestep)
    for _ in range(steps + 1):
        centroid_x = np.mean([data.qpos[a] for a in boxes])
        data.ctrl[:] = [STEER_GAIN * centroid_x, forward_target(data.time)]
        log["time"].append(np.array(data.time))
        log["qpos"].append(data.qpos.copy())
        log["qvel"].append(data.qvel.copy())
        log["ctrl"].append(data.ctrl.copy())
        mujoco.mj_step(model, data)
    return {key: np.stack(values) for key, values in log.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rollouts", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=HERE / "logs")
    args = parser.parse_args()
    model = mujoco.MjModel.from_xml_path(str(HERE / "tabletop.xml"))
    args.out.mkdir(parents=True, exist_ok=True)
    for index, child in enumerate(np.random.SeedSequence(args.seed).spawn(args.rollouts)):
        np.savez_compressed(args.out / f"run_{index:03d}.npz", **rollout(model, np.random.default_rng(child)))
    print(f"wrote {args.rollouts} roll-outs to {args.out}")


if __name__ == "__main__":
    main()
