"""Physics backends behind one :class:`Simulator` protocol, each registered as an :class:`Engine`."""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass

from energy_margin.errors import EnergyMarginError
from energy_margin.sim.base import Simulator
from energy_margin.world.scene import Scene


@dataclass(frozen=True)
class Engine:
    """A physics engine: where its simulator lives and what it is for.

    Attributes:
        name: the name users give (``--engine``).
        simulator: ``"module:Class"`` of its simulator, imported on first use; the class takes
            the scene, and ``device=`` when :attr:`devices` is not empty.
        devices: the devices it runs on, the default first; empty for the host CPU only.
        grows_together: its batched propagations run on a device: an analysis grows the trees of
            a roll-out's frames in lockstep, each round one batched call (needs ``batch`` > 1).
        records: it can record roll-outs (``generate``); an engine of propagations only cannot.
        check: ``"module:function"`` that raises one line when the engine cannot run on a device
            (its package missing, the device absent), called with the device; ``None``: always runs.

    """

    name: str
    simulator: str
    devices: tuple[str, ...] = ()
    grows_together: bool = False
    records: bool = True
    check: str | None = None


#: Every engine by name, in the order the command line lists them.
ENGINE_REGISTRY: dict[str, Engine] = {}


def register_engine(engine: Engine) -> None:
    """Add ``engine`` to :data:`ENGINE_REGISTRY` and :data:`ENGINES` (a later one of the same name replaces it)."""
    global ENGINES
    ENGINE_REGISTRY[engine.name] = engine
    ENGINES = tuple(ENGINE_REGISTRY)


ENGINES: tuple[str, ...] = ()
register_engine(Engine("mujoco", "energy_margin.sim.mujoco_backend:MujocoSimulator"))
register_engine(Engine("pybullet", "energy_margin.sim.pybullet_backend:PybulletSimulator"))
register_engine(
    Engine(
        "mujoco-warp",
        "energy_margin.sim.mujoco_warp:WarpSimulator",
        devices=("cuda", "cpu"),
        grows_together=True,
        records=False,
        check="energy_margin.sim.mujoco_warp:check_device",
    )
)


def recording_engines() -> tuple[str, ...]:
    """The engines that record roll-outs (``generate``), in registry order."""
    return tuple(name for name, engine in ENGINE_REGISTRY.items() if engine.records)


def get_engine(name: str) -> Engine:
    """The registered engine ``name``.

    Raises:
        EnergyMarginError: no engine of that name.

    """
    if name not in ENGINE_REGISTRY:
        raise EnergyMarginError(f"unknown engine {name!r}; choose one of {', '.join(ENGINE_REGISTRY)}")
    return ENGINE_REGISTRY[name]


def check_engine_device(name: str, device: str | None = None) -> None:
    """Raise one line when engine ``name`` cannot run on ``device`` here (its first device when ``None``).

    Raises:
        EnergyMarginError: an unknown engine, a device it does not have, its package missing, or
            the device absent from this machine.

    """
    spec = get_engine(name)
    if device is not None and device not in spec.devices:
        where = f"on {', '.join(spec.devices)}" if spec.devices else "on this machine's CPU only"
        raise EnergyMarginError(f"engine {name!r} runs {where}, not on `device={device}`")
    if spec.check is not None:
        module, function = spec.check.split(":")
        getattr(importlib.import_module(module), function)(device if device is not None else spec.devices[0])


def make_simulator(scene: Scene, engine: str = "mujoco", *, device: str | None = None) -> Simulator:
    """Build a simulator for ``scene`` with the named engine (imported lazily).

    Args:
        scene: the world.
        engine: a name of :data:`ENGINE_REGISTRY`.
        device: where an engine with devices runs (its first device when ``None``).

    Raises:
        EnergyMarginError: an unknown engine, or a device for an engine without devices.

    """
    spec = get_engine(engine)
    module, name = spec.simulator.split(":")
    factory: Callable[..., Simulator] = getattr(importlib.import_module(module), name)
    if not spec.devices:
        check_engine_device(engine, device)
        return factory(scene)
    return factory(scene, device=device if device is not None else spec.devices[0])


__all__ = [
    "ENGINES",
    "ENGINE_REGISTRY",
    "Engine",
    "Simulator",
    "check_engine_device",
    "get_engine",
    "make_simulator",
    "recording_engines",
    "register_engine",
]
