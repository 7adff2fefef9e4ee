"""Physics backends behind one :class:`Simulator` protocol."""

from __future__ import annotations

from energy_margin.errors import EnergyMarginError
from energy_margin.sim.base import Simulator
from energy_margin.world.scene import Scene

ENGINES = ("mujoco", "pybullet")


def make_simulator(scene: Scene, engine: str = "mujoco") -> Simulator:
    """Build a simulator for ``scene`` with the named engine (imported lazily)."""
    if engine == "mujoco":
        from energy_margin.sim.mujoco_backend import MujocoSimulator

        return MujocoSimulator(scene)
    if engine == "pybullet":
        from energy_margin.sim.pybullet_backend import PybulletSimulator

        return PybulletSimulator(scene)
    raise EnergyMarginError(f"unknown engine {engine!r}; choose one of {', '.join(ENGINES)}")


__all__ = ["ENGINES", "Simulator", "make_simulator"]
