"""Pictures of the built-in tool families for docs/howto/design.md ("Tool families"), with MuJoCo's renderer.

    python benchmarks/render_tool_families.py docs/figures

writes ``tool_faces_pushing.png`` (the four pusher faces, each pushing five cylinders, from above)
and ``tool_blades_scooping.png`` (the default blades and a long, wide, rimmed variant, from the side).
Needs the ``render`` extra (matplotlib) and an OpenGL context (EGL headless, or ``MUJOCO_GL``).
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib
import mujoco
import numpy as np

from energy_margin.data.generate import roll_out, trajectory_rng
from energy_margin.report.scene_view import _render
from energy_margin.sim.base import CompiledModel, require
from energy_margin.tasks import get_task

matplotlib.use("Agg")
import matplotlib.pyplot as plt


def _picture(task_name: str, config: dict, seconds: float, camera: tuple[float, ...], size=(480, 360)) -> np.ndarray:
    """The task's first generated trajectory (seed 0, 5 objects) at ``seconds``, from ``camera``."""
    task = get_task(task_name, config)
    trajectory = task.sample_trajectory(trajectory_rng(0, 1, 0), 5)
    simulator = task.make_simulator(5, trajectory.friction, trajectory.drive)
    steps = np.array([round(seconds / simulator.timestep)])
    for _ in roll_out(task, trajectory, simulator, trajectory_rng(0, 1, 0), steps):
        pass
    compiled = require(simulator, CompiledModel, purpose="a picture")
    model, data = compiled.model, compiled.data
    model.vis.global_.offwidth, model.vis.global_.offheight = size
    view = mujoco.MjvCamera()
    view.lookat[:], view.distance, view.azimuth, view.elevation = camera[:3], camera[3], camera[4], camera[5]
    if task.planar:  # from above, centred a little ahead of the pusher
        view.lookat[:2] = simulator.robot_positions()[:2] + np.array([0.0, 0.12])
    return _render(model, data, view, *size)


def main(out: Path) -> None:
    """Write both pictures into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    faces = [
        ("flat", {}),
        ("v, depth 0.1 m", {"pusher_face": "v", "face_depth": 0.1}),
        ("arc, depth 0.1 m", {"pusher_face": "arc", "face_depth": 0.1}),
        ("fork, 5 tines, depth 0.1 m", {"pusher_face": "fork", "face_depth": 0.1, "tine_count": 5}),
    ]
    figure, axes = plt.subplots(1, 4, figsize=(16, 3.6))
    for axis, (title, config) in zip(axes, faces, strict=True):
        axis.imshow(_picture("pushing", config, 1.2, (1.0, 0.9, 0.0, 1.1, 90.0, -89.0)))
        axis.set_title(f"pusher_face {title}")
        axis.axis("off")
    figure.tight_layout()
    figure.savefig(out / "tool_faces_pushing.png", dpi=80)
    blades = [
        ("default blades", {}),
        (
            "blade_width 0.06, tip_length 0.045, lip_height 0.004",
            {"tip_half_width": 0.03, "tip_length": 0.045, "lip_height": 0.004},
        ),
    ]
    figure, axes = plt.subplots(1, 2, figsize=(10, 4.1))
    for axis, (title, config) in zip(axes, blades, strict=True):
        axis.imshow(_picture("scooping", config, 1.25, (0.0, 0.0, 0.03, 0.28, 60.0, -25.0)))
        axis.set_title(title, fontsize=10)
        axis.axis("off")
    figure.tight_layout()
    figure.savefig(out / "tool_blades_scooping.png", dpi=80)


if __name__ == "__main__":
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "docs/figures"))
