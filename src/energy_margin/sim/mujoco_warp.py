"""The ``mujoco-warp`` engine: a tree's batched propagations on MuJoCo Warp (GPU, or CPU to test).

:class:`WarpSimulator` is a :class:`~energy_margin.sim.mujoco_backend.MujocoSimulator` whose
:class:`~energy_margin.sim.base.BatchedRollout` capability runs on `MuJoCo Warp
<https://github.com/google-deepmind/mujoco_warp>`_ instead of ``mujoco.rollout``: every round of
expansions is one batched call, one world per expansion, stepped together on the device. What
is not batched (resetting to a frame, reading the root) stays on C MuJoCo, so a tree's root is the
same on both engines and every expansion is Warp's.

Scores differ from C MuJoCo only by Warp's arithmetic: float32 physics and its own constraint
solver. Each propagation starts from a zero solver warm start, as on ``mujoco.rollout``, and its
world is computed apart from the others, so a propagation's result does not depend on the batch
it runs in (tested on CPU).

The contact and constraint buffers are sized from the frame (four times the contacts and
constraints at the root, at least 16 and 64 per world) and doubled, and the round run again,
whenever a world overflows them: no contact is ever dropped silently.
"""

from __future__ import annotations

import importlib.util
from typing import Any

import mujoco
import numpy as np

from energy_margin.errors import EnergyMarginError
from energy_margin.sim.base import IncompatibleModelsError
from energy_margin.sim.mujoco_backend import MujocoSimulator
from energy_margin.sim.mujoco_index import ModelIndex
from energy_margin.sim.mujoco_model import MujocoModelSimulator
from energy_margin.sim.mujoco_rollout import RolloutPropagator
from energy_margin.sim.mujoco_warp_kernels import engine_kernels, load_warp
from energy_margin.world.scene import Scene

__all__ = ["DEVICES", "PER_WORLD_FIELDS", "WarpModelSimulator", "WarpPropagator", "WarpSimulator", "check_device"]

#: Devices the engine runs on.
DEVICES = ("cuda", "cpu")
#: Model numbers that may differ between the worlds of one call: the models of one scene's
#: roll-outs differ in these only (friction; servo gains and masses set by a drive). Warp batches
#: them per world.
PER_WORLD_FIELDS = (
    "geom_friction",
    "body_mass",
    "body_inertia",
    "actuator_gainprm",
    "actuator_biasprm",
    "jnt_stiffness",
    "dof_damping",
)

_INSTALL = "pip install 'energy-margin[gpu]'"


def check_device(device: str) -> None:
    """Raise one line when MuJoCo Warp is not installed or ``device`` is not available.

    Raises:
        EnergyMarginError: ``mujoco_warp`` or ``warp`` cannot be imported (the ``gpu`` extra), or
            ``device`` is ``"cuda"`` and Warp finds no CUDA device.

    """
    if device not in DEVICES:
        raise EnergyMarginError(f"unknown device {device!r}; choose one of {', '.join(DEVICES)}")
    for package in ("warp", "mujoco_warp"):
        if importlib.util.find_spec(package) is None:
            raise EnergyMarginError(f"engine 'mujoco-warp' needs the package {package!r}: {_INSTALL}")
    if device == "cuda":
        wp = load_warp()
        if not wp.is_cuda_available():
            raise EnergyMarginError("device 'cuda': Warp finds no CUDA device here; use `device=cpu` (slow) or a GPU")


#: Models a propagator remembers as checked (a few groups' roll-outs).
_CHECKED_MODELS = 512


class _CaptureError(Exception):
    """A CUDA graph could not be captured; the call runs again without graphs."""


class WarpPropagator(RolloutPropagator):
    """Batched propagations of one simulator's model on MuJoCo Warp, one world per propagation.

    The same states, controls and results as :class:`~energy_margin.sim.mujoco_rollout.RolloutPropagator`
    (``mjSTATE_FULLPHYSICS`` vectors, float64 on the host); the physics runs in float32 on the
    device. The worlds are allocated for the largest batch seen so far; a smaller batch fills the
    rest with copies of its first propagation, whose results are dropped.

    Args:
        model: the simulator's compiled model (copied to the device as it is now).
        data: the simulator's data (its current state, its held controls).
        index: the objects' and the robot's addresses in ``model``.
        device: ``"cuda"`` or ``"cpu"`` (:data:`DEVICES`).

    Raises:
        EnergyMarginError: a model MuJoCo Warp cannot simulate (one line, Warp's reason), or a
            state with more than time, joints and activations (actuator history, plugins).

    """

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, index: ModelIndex, device: str) -> None:
        super().__init__(model, data, index, threads=1)
        check_device(device)
        if self.state_size != 1 + model.nq + model.nv + model.na:
            raise EnergyMarginError(
                "engine 'mujoco-warp' propagates time, joints and activations only; this model's state "
                "also holds actuator history, plugin or plasticity state"
            )
        wp = load_warp()
        import mujoco_warp as mjw

        self.device = device
        self._wp, self._mjw = wp, mjw
        probe = mujoco.MjData(model)
        mujoco.mj_setState(model, probe, self.current_state(), mujoco.mjtState.mjSTATE_FULLPHYSICS)
        mujoco.mj_forward(model, probe)
        self.contacts_per_world = max(16, 4 * int(probe.ncon))
        self.constraints_per_world = max(64, 4 * int(probe.nefc))
        with wp.ScopedDevice(device):
            try:
                self._model = mjw.put_model(model)
            except (NotImplementedError, ValueError) as error:
                raise EnergyMarginError(f"engine 'mujoco-warp' cannot simulate this model: {error}") from None
        self._model.opt.warn_overflow = 0
        self._shared = {name: getattr(self._model, name) for name in PER_WORLD_FIELDS}
        # Models checked to differ from this one in per-world numbers only, kept alive (so that no
        # new model takes a checked one's id) up to a bound.
        self._checked: dict[int, mujoco.MjModel] = {id(model): model}
        self._data: Any = None
        self.worlds = 0
        self.rounds = 0
        self.regrown = 0
        #: Whether a CUDA device replays each step as a captured graph (turned off if a capture fails).
        self.graphs = True
        self.graph_calls = 0

    def _allocate(self, worlds: int) -> None:
        with self._wp.ScopedDevice(self.device):
            self._data = self._mjw.make_data(
                self.model, nworld=worlds, nconmax=self.contacts_per_world, njmax=self.constraints_per_world
            )
        self.worlds = worlds

    def check_models(self, models: list[mujoco.MjModel]) -> None:
        """Raise unless every model differs from this one in :data:`PER_WORLD_FIELDS` only.

        Raises:
            IncompatibleModelsError: a model differs from this one in anything else.

        """
        for other in {id(model): model for model in models}.values():
            if id(other) not in self._checked:
                _check_same_structure(self.model, other)
                if len(self._checked) >= _CHECKED_MODELS:
                    self._checked = {id(self.model): self.model}
                self._checked[id(other)] = other

    def _per_world(self, models: list[mujoco.MjModel] | None) -> dict[str, np.ndarray]:
        """Each propagation's values of the :data:`PER_WORLD_FIELDS` that differ from this model's."""
        if models is None:
            return {}
        # A call holds a few roll-outs' models over thousands of rows: compare each model once.
        distinct = {id(model): model for model in models}
        self.check_models(list(distinct.values()))
        order = {key: at for at, key in enumerate(distinct)}
        rows = np.fromiter((order[id(model)] for model in models), dtype=np.int64, count=len(models))
        per_world = {}
        for name in PER_WORLD_FIELDS:
            values = [getattr(model, name) for model in distinct.values()]
            if any(not np.array_equal(value, getattr(self.model, name)) for value in values):
                per_world[name] = np.stack(values)[rows]
        return per_world

    def _run(
        self,
        initial: np.ndarray,
        controls: np.ndarray,
        n_steps: np.ndarray,
        *,
        every_step: bool,
        period: int = 1,
        models: list[mujoco.MjModel] | None = None,
    ) -> np.ndarray:
        """Step every world; the state after each step (every_step) or after its own last one.

        ``controls`` (k, n_chunks, control_size): step ``t`` holds ``controls[:, t // period]``.
        """
        k = controls.shape[0]
        if k > self.worlds:
            self._allocate(k)
        per_world = self._per_world(models)
        while True:
            try:
                out = self._attempt(initial, controls, n_steps, every_step, period, per_world)
            except _CaptureError:
                # A capture leaves nothing run: the round starts again with plain launches.
                out = self._attempt(initial, controls, n_steps, every_step, period, per_world)
            overflow = self._data.overflow.numpy()[:k]
            if not overflow.any():
                return out
            # A world ran out of contact or constraint rows: double them and run the round again.
            self.contacts_per_world *= 2
            self.constraints_per_world *= 2
            self.regrown += 1
            self._allocate(self.worlds)

    def _attempt(
        self,
        initial: np.ndarray,
        controls: np.ndarray,
        n_steps: np.ndarray,
        every_step: bool,
        period: int,
        per_world: dict[str, np.ndarray],
    ) -> np.ndarray:
        wp, mjw, model, data = self._wp, self._mjw, self.model, self._data
        k = controls.shape[0]
        steps = int(n_steps.max())
        worlds = self.worlds
        pad = np.r_[np.arange(k), np.zeros(worlds - k, dtype=int)]
        initial, controls = initial[pad], controls[pad]
        with wp.ScopedDevice(self.device):
            for name, shared in self._shared.items():
                if name in per_world:
                    values = np.ascontiguousarray(per_world[name][pad], dtype=np.float32)
                    setattr(self._model, name, wp.array(values, dtype=shared.dtype))
                else:
                    setattr(self._model, name, shared)
        nu, nv, nbody = int(model.nu), int(model.nv), int(model.nbody)
        parts = np.split(controls, np.cumsum([nu, nv, 6 * nbody]), axis=2)
        kernels = engine_kernels()
        with wp.ScopedDevice(self.device):

            def upload(array: np.ndarray) -> Any:
                # Empty parts still need one column: Warp arrays have no zero-sized axis here.
                if array.shape[-1] == 0:
                    array = np.zeros((*array.shape[:-1], 1))
                return wp.array(np.ascontiguousarray(array, dtype=np.float32), dtype=float)

            sequences = [upload(part) for part in parts]
            nq = int(model.nq)
            data.time.assign(initial[:, 0].astype(np.float32))
            data.qpos.assign(initial[:, 1 : 1 + nq].astype(np.float32))
            data.qvel.assign(initial[:, 1 + nq : 1 + nq + nv].astype(np.float32))
            if model.na:
                data.act.assign(initial[:, 1 + nq + nv :].astype(np.float32))
            data.qacc_warmstart.zero_()
            data.overflow.zero_()
            ends = wp.array(np.where(np.arange(worlds) < k, n_steps[pad], -1).astype(np.int32), dtype=int)
            out = wp.zeros((worlds, steps if every_step else 1, self.state_size), dtype=float)
            targets = [data.ctrl, data.qfrc_applied, data.xfrc_applied, data.mocap_pos, data.mocap_quat]
            # The step number lives on the device, so one step is the same launches every time:
            # on CUDA they are captured once as a graph and replayed.
            clock = wp.zeros(1, dtype=int)

            def one_step() -> None:
                wp.launch(kernels["hold_controls"], dim=worlds, inputs=[clock, period, *sequences, *targets])
                mjw.step(self._model, data)
                wp.launch(
                    kernels["keep_state"],
                    dim=worlds,
                    inputs=[clock, int(every_step), ends, data.time, data.qpos, data.qvel, data.act, out],
                )
                wp.launch(kernels["tick"], dim=1, inputs=[clock])

            self._steps(one_step, steps)
            result = out.numpy()[:k].astype(np.float64)
        self.rounds += 1
        return result

    def _steps(self, one_step: Any, steps: int) -> None:
        """Run ``one_step`` ``steps`` times: replayed as a CUDA graph on a GPU, launched on a CPU."""
        wp = self._wp
        if self.device != "cuda" or not self.graphs or steps < 2:
            for _ in range(steps):
                one_step()
            return
        try:
            with wp.ScopedCapture() as capture:
                one_step()
        except Exception:
            self.graphs = False
            raise _CaptureError from None
        for _ in range(steps):
            wp.capture_launch(capture.graph)
        self.graph_calls += 1

    def _roll_all(self, initial: np.ndarray, controls: np.ndarray) -> np.ndarray:
        k, steps = controls.shape[:2]
        return self._run(initial, controls, np.full(k, steps), every_step=True)

    def _roll_to(
        self,
        initial: np.ndarray,
        chunks: np.ndarray,
        period: int,
        n_steps: np.ndarray,
        models: list[mujoco.MjModel] | None = None,
    ) -> np.ndarray:
        # The chunks go to the device as they are: a step reads its period's (no per-step copy).
        return self._run(initial, chunks, np.asarray(n_steps), every_step=False, period=period, models=models)[:, 0]

    def close(self) -> None:
        """Free the device arrays."""
        super().close()
        self._data = None
        self.worlds = 0


def _check_same_structure(model: mujoco.MjModel, other: mujoco.MjModel) -> None:
    """Raise unless ``other`` is ``model`` but for the :data:`PER_WORLD_FIELDS`.

    Raises:
        IncompatibleModelsError: they differ elsewhere.

    """
    for name in dir(model):
        if name.startswith("_") or name in PER_WORLD_FIELDS:
            continue
        mine = getattr(model, name)
        if isinstance(mine, np.ndarray) and not np.array_equal(mine, getattr(other, name)):
            raise IncompatibleModelsError(
                f"engine 'mujoco-warp' propagates models together only when they differ in "
                f"{', '.join(PER_WORLD_FIELDS)}; these also differ in {name}"
            )


class _WarpPropagation:
    """The capability a Warp simulator replaces: its batched propagations run on MuJoCo Warp."""

    device: str
    model: mujoco.MjModel
    data: mujoco.MjData
    index: ModelIndex
    pruned_contacts: Any
    _warp_propagator: WarpPropagator | None

    def keep_object_contacts(self) -> Any:
        """Simulate the analysis model from now on; the device copy follows the rewritten model."""
        before = self.pruned_contacts
        report = super().keep_object_contacts()  # type: ignore[misc]
        if before is None:
            self._warp_propagator = None
        return report

    def rollout_propagator(self, threads: int = 1) -> WarpPropagator:
        """The Warp propagator of this simulator's model (one per simulator; ``threads`` is unused)."""
        if self._warp_propagator is None:
            self._warp_propagator = WarpPropagator(self.model, self.data, self.index, self.device)
        return self._warp_propagator


class WarpSimulator(_WarpPropagation, MujocoSimulator):
    """A MuJoCo simulator whose batched propagations run on MuJoCo Warp (engine ``"mujoco-warp"``).

    Args:
        scene: the world description.
        device: ``"cuda"`` or ``"cpu"`` (:data:`DEVICES`).
        model: a compiled model of ``scene`` to simulate instead of building one; with ``index``.
        index: the objects' and the robot's addresses in ``model``.

    Raises:
        EnergyMarginError: MuJoCo Warp is not installed, or ``device`` is not available.

    """

    def __init__(
        self,
        scene: Scene,
        *,
        device: str = "cpu",
        model: mujoco.MjModel | None = None,
        index: ModelIndex | None = None,
    ) -> None:
        check_device(device)
        super().__init__(scene, model=model, index=index)
        self.device = device
        self._warp_propagator = None


class WarpModelSimulator(_WarpPropagation, MujocoModelSimulator):
    """A simulator of a compiled user model (a scene file's) whose batched propagations run on MuJoCo Warp.

    Args:
        model: the compiled model (not copied: one simulator per model).
        scene: the objects' description; ``scene.objects[i].name`` is object i's body.
        object_joints: joint id of each object's free joint (or first upright joint).
        robot_joints: ids of the robot's hinge and slide joints, in ``robot_q`` order.
        still: hold the robot where each reset puts it
            (:class:`~energy_margin.sim.mujoco_model.MujocoModelSimulator`).
        coasting: the robot keeps the velocities each reset gives it (the same class).
        robot_armature: the robot joints' armature when still or coasting (the same class).
        device: ``"cuda"`` or ``"cpu"`` (:data:`DEVICES`).

    Raises:
        EnergyMarginError: MuJoCo Warp is not installed, or ``device`` is not available.

    """

    def __init__(
        self,
        model: mujoco.MjModel,
        scene: Scene,
        *,
        object_joints: list[int],
        robot_joints: list[int],
        still: bool = False,
        coasting: bool = False,
        robot_armature: float | None = None,
        device: str = "cpu",
    ) -> None:
        check_device(device)
        super().__init__(
            model, scene, object_joints=object_joints, robot_joints=robot_joints, still=still, coasting=coasting,
            robot_armature=robot_armature,
        )  # fmt: skip
        self.device = device
        self._warp_propagator = None
