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
        contact_models: the contact models (``AnalyzerConfig.contacts``) its simulators build:
            ``"recorded"``, the dataset's own, and ``"fast"``, a task's cheaper MuJoCo stand-ins.
        continues: its simulators continue the scripted motion from a tree's states in batches
            (success continuation, :mod:`energy_margin.analysis.continuation`).
        model_simulator: ``"module:Class"`` of its simulator of a compiled user model (a scene
            file's), taking the model, the scene, ``object_joints=``, ``robot_joints=``, ``still=``,
            ``coasting=`` and ``device=`` when :attr:`devices` is not empty; ``None``: it simulates
            built-in scenes only.

    """

    name: str
    simulator: str
    devices: tuple[str, ...] = ()
    grows_together: bool = False
    records: bool = True
    check: str | None = None
    contact_models: tuple[str, ...] = ("recorded",)
    continues: bool = False
    model_simulator: str | None = None


#: Every engine by name, in the order the command line lists them.
ENGINE_REGISTRY: dict[str, Engine] = {}


def register_engine(engine: Engine) -> None:
    """Add ``engine`` to :data:`ENGINE_REGISTRY` and :data:`ENGINES` (a later one of the same name replaces it)."""
    global ENGINES
    ENGINE_REGISTRY[engine.name] = engine
    ENGINES = tuple(ENGINE_REGISTRY)


ENGINES: tuple[str, ...] = ()
register_engine(
    Engine(
        "mujoco",
        "energy_margin.sim.mujoco_backend:MujocoSimulator",
        contact_models=("recorded", "fast"),
        continues=True,
        model_simulator="energy_margin.sim.mujoco_model:MujocoModelSimulator",
    )
)
register_engine(Engine("pybullet", "energy_margin.sim.pybullet_backend:PybulletSimulator"))
register_engine(
    Engine(
        "mujoco-warp",
        "energy_margin.sim.mujoco_warp:WarpSimulator",
        devices=("cuda", "cpu"),
        grows_together=True,
        records=False,
        check="energy_margin.sim.mujoco_warp:check_device",
        contact_models=("recorded", "fast"),
        continues=True,
        model_simulator="energy_margin.sim.mujoco_warp:WarpModelSimulator",
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


def _build(spec: Engine, path: str, device: str | None, *args: object, **kwargs: object) -> Simulator:
    """Import ``path`` ("module:Class") and build it, with ``device=`` for an engine with devices."""
    module, name = path.split(":")
    factory: Callable[..., Simulator] = getattr(importlib.import_module(module), name)
    if not spec.devices:
        check_engine_device(spec.name, device)
        return factory(*args, **kwargs)
    return factory(*args, **kwargs, device=device if device is not None else spec.devices[0])


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
    return _build(spec, spec.simulator, device, scene)


def make_model_simulator(
    model: object,
    scene: Scene,
    engine: str = "mujoco",
    *,
    object_joints: list[int],
    robot_joints: list[int],
    still: bool = False,
    coasting: bool = False,
    robot_armature: float | None = None,
    device: str | None = None,
) -> Simulator:
    """Build a simulator of a compiled user model (``mujoco.MjModel``, not copied) with the named engine.

    Args:
        model: the compiled model; ``scene.objects[i].name`` is object i's body in it.
        scene: the objects' description.
        engine: a name of :data:`ENGINE_REGISTRY` whose :attr:`Engine.model_simulator` is set.
        object_joints: joint id of each object's free joint (or first upright joint).
        robot_joints: ids of the robot's hinge and slide joints, in ``robot_q`` order.
        still: hold the robot where each reset puts it.
        coasting: the robot keeps the velocities each reset gives it.
        robot_armature: the robot joints' armature when still or coasting, kg m^2 or kg (``None``:
            :data:`~energy_margin.sim.mujoco_model.STILL_ARMATURE` or
            :data:`~energy_margin.sim.mujoco_model.COASTING_ARMATURE`).
        device: where an engine with devices runs (its first device when ``None``).

    Raises:
        EnergyMarginError: an unknown engine, one that simulates built-in scenes only, or a device
            for an engine without devices.

    """
    spec = get_engine(engine)
    if spec.model_simulator is None:
        users = ", ".join(name for name, other in ENGINE_REGISTRY.items() if other.model_simulator is not None)
        raise EnergyMarginError(f"engine {engine!r} simulates built-in scenes only; a model file runs on {users}")
    armature = {} if robot_armature is None else {"robot_armature": robot_armature}
    return _build(spec, spec.model_simulator, device, model, scene, object_joints=object_joints,
                  robot_joints=robot_joints, still=still, coasting=coasting, **armature)  # fmt: skip


__all__ = [
    "ENGINES",
    "ENGINE_REGISTRY",
    "Engine",
    "Simulator",
    "check_engine_device",
    "get_engine",
    "make_model_simulator",
    "make_simulator",
    "recording_engines",
    "register_engine",
]
