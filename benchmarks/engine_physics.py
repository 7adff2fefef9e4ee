"""One object on a plane in MuJoCo and in PyBullet: friction work, slide distance, one wrench's push.

The checks of ``tests/sim/test_pybullet_backend.py``, measured and written as a results file
(docs/reference/engines.md quotes it). Every scene is one or two objects on a ground plane, no
robot, at 1/240 s:

* a 0.2 kg object sliding from 0.5 m/s, μ = 0.5, for 0.25 s: the friction work the engine
  reports (against −½ m v0²) and the distance slid (against v0² / (2 μ g));
* a resting object, μ = 0.3, one wrench for 0.15 s: 1.2 N along x with 2e-4 N m about z (the
  displacement and the height of its centre), and a diagonal force (1.2, 0.5) N (against
  isotropic Coulomb friction, whose displacement is along the force);
* two 5 cm cylinders overlapping 40 mm sideways: the penetration each engine reports.

Each for an upright cylinder (r 5 cm, 3 cm high) and a free box (10 × 8 × 4 cm).

    python benchmarks/engine_physics.py --out docs/figures/engine_physics.json

Without PyBullet it prints one ``skip:`` line.
"""

from __future__ import annotations

import argparse
import datetime
import importlib.util
import json
from pathlib import Path
from typing import Any

import numpy as np

from bench_analysis import machine
from energy_margin.runs.versions import engine_versions
from energy_margin.sim import make_simulator
from energy_margin.world.scene import Geom, RigidObject, Scene
from energy_margin.world.state import FrameState

__all__ = ["coulomb_displacement", "measure"]

G = 9.81
TIMESTEP = 1.0 / 240.0
MASS = 0.2
ENGINES = ("mujoco", "pybullet")
#: (shape, object motion) of the two objects measured.
OBJECTS = {"cylinder": ("cylinder", "upright"), "box": ("box", "free")}
SLIDE = {"friction": 0.5, "speed": 0.5, "steps": 60}
PUSH = {"friction": 0.3, "steps": 36}
WRENCH_X = (1.2, 0.0, 0.0, 0.0, 0.0, 2e-4)
WRENCH_DIAGONAL = (1.2, 0.5, 0.0, 0.0, 0.0, 0.0)


def _scene(n_objects: int, shape: str, motion: str, friction: float) -> Scene:
    """Objects of one shape on a ground plane at z = 0, no robot."""
    geom = Geom("box", (0.05, 0.04, 0.02)) if shape == "box" else Geom("cylinder", (0.05, 0.015))
    objects = tuple(RigidObject(f"object{i}", geom, MASS) for i in range(n_objects))
    statics = (Geom("plane", (5.0, 5.0), name="ground"),)
    return Scene(
        objects=objects, robot=None, statics=statics, friction=friction, timestep=TIMESTEP, object_motion=motion
    )


def _frame(positions: np.ndarray, velocities: np.ndarray | None = None) -> FrameState:
    """Objects at ``positions`` (n, 3), level, with ``velocities`` (n, 6) or at rest."""
    n = len(positions)
    moving = np.zeros((n, 6)) if velocities is None else velocities
    return FrameState(positions, np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)), moving, np.zeros(0), np.zeros(0))


def coulomb_displacement(force: tuple[float, float], friction: float, duration: float) -> np.ndarray:
    """Displacement [m] of a resting body of ``MASS`` under a constant horizontal ``force`` [N].

    Isotropic Coulomb friction ``friction · m · g`` opposes the motion, which is along the force.
    """
    direction = np.asarray(force, dtype=float)
    magnitude = float(np.linalg.norm(direction))
    acceleration = max(magnitude - friction * MASS * G, 0.0) / MASS
    return 0.5 * acceleration * duration**2 * direction / magnitude


def _slide(engine: str, shape: str, motion: str) -> dict[str, float]:
    """Friction work [mJ], distance [mm] and final speed [m/s] of an object sliding to rest."""
    scene = _scene(1, shape, motion, SLIDE["friction"])
    simulator = make_simulator(scene, engine)
    half_height = scene.objects[0].geom.size[-1]
    velocity = np.zeros((1, 6))
    velocity[0, 0] = SLIDE["speed"]
    simulator.reset(_frame(np.array([[0.0, 0.0, half_height]]), velocity))
    work = simulator.step(SLIDE["steps"], track_friction_work=True)
    return {
        "friction_work_mj": 1e3 * float(work),
        "slide_mm": 1e3 * float(simulator.object_positions()[0, 0]),
        "final_speed_m_s": float(abs(simulator.object_velocities()[0, 0])),
    }


def _push(engine: str, shape: str, motion: str, wrench: tuple[float, ...]) -> list[float]:
    """Position [mm] of a resting object after ``wrench`` for 0.15 s."""
    scene = _scene(1, shape, motion, PUSH["friction"])
    simulator = make_simulator(scene, engine)
    half_height = scene.objects[0].geom.size[-1]
    simulator.reset(_frame(np.array([[0.0, 0.0, half_height]])))
    simulator.set_object_wrenches(np.array([wrench]))
    simulator.step(PUSH["steps"])
    return [1e3 * float(v) for v in simulator.object_positions()[0]]


def _penetration(engine: str) -> float | None:
    """Depth [mm] each engine reports for two cylinders overlapping 40 mm sideways (None: none)."""
    simulator = make_simulator(_scene(2, "cylinder", "free", 0.3), engine)
    simulator.reset(_frame(np.array([[0.0, 0.0, 0.015], [0.06, 0.0, 0.015]])))
    found = {(a, b): depth for a, b, depth in simulator.object_penetrations()}
    return 1e3 * float(found[(0, 1)]) if (0, 1) in found else None


def measure() -> dict[str, Any]:
    """Every check in both engines, and the analytic values they are held against (mJ, mm)."""
    slide_distance = SLIDE["speed"] ** 2 / (2 * SLIDE["friction"] * G)
    duration = PUSH["steps"] * TIMESTEP
    engines: dict[str, Any] = {}
    for engine in ENGINES:
        engines[engine] = {
            name: {
                "slide": _slide(engine, shape, motion),
                "push_x": _push(engine, shape, motion, WRENCH_X),
                "push_diagonal": _push(engine, shape, motion, WRENCH_DIAGONAL),
                "rest_height_mm": 1e3 * _scene(1, shape, motion, 0.3).objects[0].geom.size[-1],
            }
            for name, (shape, motion) in OBJECTS.items()
        }
        engines[engine]["penetration_mm"] = _penetration(engine)
    return {
        "analytic": {
            "friction_work_mj": -0.5e3 * MASS * SLIDE["speed"] ** 2,
            "slide_mm": 1e3 * slide_distance,
            "push_x_mm": 1e3 * float(coulomb_displacement(WRENCH_X[:2], PUSH["friction"], duration)[0]),
            "push_diagonal_mm": [
                1e3 * float(v) for v in coulomb_displacement(WRENCH_DIAGONAL[:2], PUSH["friction"], duration)
            ],
        },
        "engines": engines,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--out", type=Path, required=True, help="the JSON file to write")
    args = parser.parse_args()
    if importlib.util.find_spec("pybullet") is None:
        print("skip: PyBullet is not installed (pip install 'energy-margin[pybullet]')")
        return
    figures = {
        "command": "python benchmarks/engine_physics.py --out FILE",
        "date": datetime.date.today().isoformat(),
        "machine": machine(),
        "versions": {**engine_versions(), **engine_versions("pybullet")},
        "timestep_s": TIMESTEP,
        "mass_kg": MASS,
        "slide": SLIDE,
        "push": PUSH,
        "wrench_x": WRENCH_X,
        "wrench_diagonal": WRENCH_DIAGONAL,
        **measure(),
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(figures, indent=2) + "\n", encoding="utf-8")
    print(json.dumps(figures["analytic"], indent=1))
    print(json.dumps(figures["engines"], indent=1))


if __name__ == "__main__":
    main()
