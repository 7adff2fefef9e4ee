"""A task built from a scene file: the user's MuJoCo model, declared motion, randomisation and sets.

:class:`SceneTask` (``"scene"``) records the scene file and the hashes of the file and its compiled model:
a dataset written from it rebuilds the same task, or refuses to (``dataset.json: task_config``) when either changed.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from energy_margin.errors import InvalidDataError, InvalidParameterError
from energy_margin.sim.base import CompiledModel, ModelCommand, ModelCommands, Simulator, require
from energy_margin.sim.mujoco_index import ModelIndex, object_owners
from energy_margin.tasks.base import DesignParameter, Region, Task, WrenchLimits
from energy_margin.tasks.command import control_steps
from energy_margin.tasks.motion import RobotState, Trajectory
from energy_margin.tasks.recorded_path import RECORDED_ARMATURE, PathForceTable, path_drive, path_drive_size
from energy_margin.tasks.scene_defaults import object_armature
from energy_margin.tasks.scene_layout import draw_layout
from energy_margin.tasks.scene_model import LoadedScene, load_scene_cached
from energy_margin.tasks.scene_regions import SceneRegions
from energy_margin.tasks.scene_spec import BOUNDS_MARGIN
from energy_margin.tasks.scene_task_config import BASE_FIELDS, SceneTaskConfig, design_config_class, design_overrides
from energy_margin.tasks.state_box import StateBox, box_around_model
from energy_margin.world.scene import Geom, RigidObject, Scene
from energy_margin.world.state import FrameState

__all__ = ["SceneTask", "SceneTaskConfig", "design_overrides"]

#: Redraws of an object layout that overlaps the robot or an obstacle before giving up.
_LAYOUT_ATTEMPTS = 200
#: Deepest accepted contact penetration of a freshly placed object, m.
_PLACEMENT_TOLERANCE = 1e-3
#: Recorded paths whose force tables a task keeps (frames arrive roll-out by roll-out).
_PATH_TABLES = 256


class SceneTask(SceneRegions, Task):
    """The task a scene file declares (see ``docs/howto/scenes.md``)."""

    name = "scene"
    config_class = SceneTaskConfig
    engines = ("mujoco", "mujoco-warp")
    config: SceneTaskConfig

    def __init__(
        self,
        config: SceneTaskConfig | None = None,
        *,
        loaded: LoadedScene | None = None,
        design: Mapping[str, Any] | None = None,
    ) -> None:
        """Build from ``config.scene_file`` or, with ``loaded``, from a scene resolved in memory.

        Args:
            config: the scene file and the hashes it must match (and the values of its
                ``[design]`` parameters, in a configuration built by :meth:`from_dict`).
            loaded: a scene already resolved against its model (a wrapped environment's model,
                :func:`~energy_margin.tasks.scene_model.resolve_scene`); ``config`` is then ignored
                and the task cannot be rebuilt from a dataset.
            design: values of the file's ``[design]`` parameters (over those of ``config``); the
                model is compiled with them (:func:`~energy_margin.tasks.scene_model.apply_design`).

        """
        if loaded is not None:
            path = loaded.spec.path
            config = SceneTaskConfig(scene_file=str(path))
        elif config is None or not config.scene_file:
            raise InvalidParameterError(
                "scene_file", "must name the scene file the task is built from: pass `scene_file=SCENE.toml`"
            )
        else:
            path = Path(config.scene_file).resolve()
            loaded = load_scene_cached(path, {**design_overrides(config), **dict(design or {})})
        if config.scene_sha256 and config.scene_sha256 != loaded.spec.text_sha256:
            raise InvalidDataError(
                f"scene file {path} changed since these data were made "
                f"(sha256 {config.scene_sha256[:12]}…, now {loaded.spec.text_sha256[:12]}…)"
            )
        if config.model_sha256 and config.model_sha256 != loaded.model_sha256:
            raise InvalidDataError(
                f"the model of {path} ({loaded.spec.mjcf.name}) changed since these data were made "
                f"(sha256 {config.model_sha256[:12]}…, now {loaded.model_sha256[:12]}…)"
            )
        spec = loaded.spec
        model = loaded.model
        resolved = design_config_class(loaded.design_values)(
            duration=spec.motion.duration,
            timestep=float(model.opt.timestep),
            likelihood_lambda=loaded.perturbation.likelihood_lambda,
            max_duration=loaded.perturbation.max_duration,
            scene_file=str(path),
            scene_sha256=spec.text_sha256,
            model_sha256=loaded.model_sha256,
        )
        super().__init__(resolved)
        self.loaded = loaded
        unset = "derived" if "lambda" in loaded.perturbation.derived else "default"
        self.lambda_origin = "set" if spec.likelihood_lambda is not None else unset
        self.fixed_objects = loaded.n_objects
        self.control_period = spec.motion.control_period
        self._kinematics = mujoco.MjData(model)
        # The objects' coordinates in the model (partially jointed upright objects included).
        self._index = ModelIndex.of(
            model,
            self.build_scene(loaded.n_objects, 0.5),
            object_joints=list(loaded.object_joints),
            robot_joints=list(loaded.robot_joints),
        )
        self._success: Region | None = None
        self._placement: Simulator | None = None
        self._path_tables: dict[bytes, PathForceTable] = {}

    @classmethod
    def from_dict(cls, values: dict[str, Any] | None) -> Task:
        """Build from ``{"scene_file": ..., "scene_sha256": ..., "model_sha256": ...}`` and design values.

        The other settings are the file's; stored ones (``duration``, ``timestep``, ...) are accepted
        and replaced by the file's values, which the hashes pin. Any other key must name one of the
        file's ``[design]`` parameters: its value is set on the model before it is compiled.
        """
        values = dict(values or {})
        known = set(BASE_FIELDS)
        for key in ("scene_file", "scene_sha256", "model_sha256"):
            if key in values and not isinstance(values[key], str):
                raise InvalidParameterError(key, f"must be a string, got {values[key]!r}")
        config = SceneTaskConfig(
            scene_file=values.get("scene_file", ""),
            scene_sha256=values.get("scene_sha256", ""),
            model_sha256=values.get("model_sha256", ""),
        )
        # Keys the file does not declare in [design] are refused by name where the model is compiled.
        return cls(config, design={key: value for key, value in values.items() if key not in known})

    def _settings(self) -> dict[str, Any]:
        """The scene file and its ``[design]`` values; the hashes pin this model, not a variant's."""
        return {"scene_file": self.config.scene_file, **dict(self.loaded.design_values)}

    def model_sha256(self, n_objects: int) -> str:
        """SHA-256 of the compiled model (with the file's templates and design), as ``task_config`` records it."""
        self._check_objects(n_objects)
        return self.loaded.model_sha256

    def design_fields(self) -> tuple[str, ...]:
        """Only the ``[design]`` parameters: the file's other settings are pinned by its hash."""
        return tuple(entry.name for entry in self.loaded.spec.design)

    def design_space(self) -> tuple[DesignParameter, ...]:
        """The scene file's ``[design]`` parameters over their declared ranges."""
        return tuple(
            DesignParameter(entry.name, entry.doc or entry.describe(), low=entry.low, high=entry.high)
            for entry in self.loaded.spec.design
        )

    @property
    def label(self) -> str:
        """``scene file PATH``."""
        return f"scene file {self.loaded.spec.path}"

    # -- the world -------------------------------------------------------------------------

    def _check_objects(self, n_objects: int) -> None:
        if n_objects != self.loaded.n_objects:
            raise InvalidParameterError(
                "n_objects",
                f"must be {self.loaded.n_objects}: the scene file declares {self.loaded.n_objects} objects, "
                f"not {n_objects}",
            )

    def build_scene(self, n_objects: int, friction: float, drive: np.ndarray | None = None) -> Scene:
        """The objects' description (bounding boxes, masses); the physics is the model itself."""
        self._check_objects(n_objects)
        loaded = self.loaded
        scale = float(drive[1]) if drive is not None else 1.0
        objects = tuple(
            RigidObject(
                name=name,
                geom=Geom("box", tuple(float(v) for v in np.maximum(loaded.object_half_extents[i], 1e-4))),
                mass=float(loaded.object_inertials[0][i]) * scale,
            )
            for i, name in enumerate(loaded.object_names)
        )
        return Scene(
            objects=objects,
            robot=None,
            statics=(),
            friction=friction,
            timestep=float(loaded.model.opt.timestep),
            gravity=tuple(float(g) for g in loaded.model.opt.gravity),  # type: ignore[arg-type]
            object_motion=loaded.spec.object_joints or "free",  # resolved against the model
        )

    def compiled_model(self, friction: float, drive: np.ndarray | None = None) -> mujoco.MjModel:
        """A copy of the compiled model with the trajectory's friction and object mass scale."""
        loaded = self.loaded
        model = copy.copy(loaded.model)
        if loaded.spec.friction_range is not None:
            model.geom_friction[:, 0] = friction
        if drive is not None and float(drive[1]) != 1.0:
            # Every body of each object's rigid subtree.
            bodies = np.flatnonzero(object_owners(model, loaded.object_bodies) >= 0)
            model.body_mass[bodies] *= float(drive[1])
            model.body_inertia[bodies] *= float(drive[1])
        return model

    def make_simulator(
        self, n_objects: int, friction: float, drive: np.ndarray | None = None, engine: str = "mujoco", *,
        device: str | None = None,
    ) -> Simulator:  # fmt: skip
        """A simulator of the scene's compiled model on ``engine`` (one with a model simulator: MuJoCo's)."""
        from energy_margin.sim import make_model_simulator

        recorded = self.loaded.spec.motion.robot == "recorded"
        return make_model_simulator(
            self.compiled_model(friction, drive),
            self.build_scene(n_objects, friction, drive),
            engine,
            object_joints=list(self.loaded.object_joints),
            robot_joints=list(self.loaded.robot_joints),
            still=self.loaded.spec.motion.robot == "still",
            coasting=self.loaded.spec.motion.robot == "coasting" or recorded,  # a recorded path: coasting, driven
            robot_armature=RECORDED_ARMATURE if recorded else None,
            device=device,
        )

    def robot_dofs(self) -> int:
        """Robot hinge and slide joints plus seven coordinates per mocap body."""
        return len(self.loaded.robot_joints) + 7 * int(self.loaded.model.nmocap)

    def drive_size(self) -> int:
        """The motion's time scale and the objects' mass scale, then a recorded path's knots (``"recorded"``)."""
        motion = self.loaded.spec.motion
        if motion.robot == "recorded":
            return path_drive_size(motion.path_points, len(self.loaded.robot_joints))
        return 2

    def recorded_drive(self, time: np.ndarray, qpos: np.ndarray, qvel: np.ndarray) -> np.ndarray:
        """The drive parameters of a roll-out recorded at ``time`` (n,) s with ``qpos`` (n, nq), ``qvel`` (n, nv).

        Scales of 1; with ``robot = "recorded"``, the robot joints' path after them (:func:`path_drive`).
        """
        motion = self.loaded.spec.motion
        if motion.robot != "recorded":
            return np.ones(self.drive_size())
        model, joints = self.loaded.model, list(self.loaded.robot_joints)
        q = np.asarray(qpos)[:, model.jnt_qposadr[joints]]
        v = np.asarray(qvel)[:, model.jnt_dofadr[joints]]
        return path_drive(time, q, v, points=motion.path_points)

    def default_friction(self) -> float:
        """The sliding friction of the first object geom of the model (used without a friction range)."""
        loaded = self.loaded
        geom = int(loaded.object_geoms[0][0])
        return float(loaded.model.geom_friction[geom, 0])

    # -- the motion ------------------------------------------------------------------------

    def sample_trajectory(self, rng: np.random.Generator, n_objects: int) -> Trajectory:
        """Friction, time and mass scales, then object start poses placed without overlaps."""
        self._check_objects(n_objects)
        spec = self.loaded.spec
        if spec.motion.robot == "recorded":
            raise InvalidDataError(
                f'{spec.path}: motion.robot: "recorded" follows the paths of recorded roll-outs: make its data with '
                "record, not generate"
            )
        friction = (
            float(rng.uniform(*spec.friction_range)) if spec.friction_range is not None else self.default_friction()
        )
        time_scale = float(rng.uniform(*spec.time_scale)) if spec.time_scale is not None else 1.0
        mass_scale = float(rng.uniform(*spec.mass_scale)) if spec.mass_scale is not None else 1.0
        drive = np.array([time_scale, mass_scale])
        simulator = self.make_simulator(n_objects, friction, drive)
        deepest = (0, -1, 0.0)
        for _ in range(_LAYOUT_ATTEMPTS):
            pos, quat = draw_layout(self.loaded, self._index, rng)
            initial = self.initial_frame(pos, quat, drive)
            simulator.reset(initial)
            self._apply_start_command(simulator, drive)
            overlaps = [contact for contact in simulator.object_penetrations() if contact[2] > _PLACEMENT_TOLERANCE]
            if not overlaps:
                return Trajectory(initial=initial, friction=friction, drive=drive)
            deepest = max(overlaps, key=lambda contact: contact[2])
        obj, other, depth = deepest
        names = self.loaded.object_names
        what = names[other] if other >= 0 else "the robot or an obstacle"
        raise InvalidDataError(
            f"{spec.path}: randomize.start: cannot place the {n_objects} objects without overlap in "
            f"{_LAYOUT_ATTEMPTS} draws (the last: {names[obj]} {1000 * depth:.1f} mm into {what}); widen the start "
            "ranges, lower min_separation or move the start ranges off the robot"
        )

    def _apply_start_command(self, simulator: Simulator, drive: np.ndarray) -> None:
        command = self.model_command(drive, 0.0)
        if command is not None:
            require(simulator, ModelCommands, purpose="a scene file's motion").set_model_command(command)
        compiled = require(simulator, CompiledModel, purpose="a scene file's start layout")
        mujoco.mj_forward(compiled.model, compiled.data)

    def initial_frame(self, object_pos: np.ndarray, object_quat: np.ndarray, drive: np.ndarray) -> FrameState:
        """The start frame: objects at rest at these poses, the robot at its start and the motion's t = 0."""
        loaded = self.loaded
        model = loaded.model
        robot_q = [loaded.initial_qpos[model.jnt_qposadr[j]] for j in loaded.robot_joints]
        mocap = self._mocap_coordinates(0.0, drive)
        n = loaded.n_objects
        return FrameState(
            object_pos=np.asarray(object_pos, dtype=float),
            object_quat=np.asarray(object_quat, dtype=float),
            object_vel=np.zeros((n, 6)),
            robot_q=np.concatenate([np.array(robot_q, dtype=float), mocap]),
            robot_v=np.zeros(self.robot_dofs()),
        )

    def _mocap_coordinates(self, time: float, drive: np.ndarray) -> np.ndarray:
        model = self.loaded.model
        poses = self.loaded.motion.mocap_at(time * float(drive[0]))
        if poses is None:
            data = self._kinematics
            mujoco.mj_resetData(model, data)
            return np.concatenate([data.mocap_pos.ravel(), data.mocap_quat.ravel()])
        return np.concatenate([poses[0].ravel(), poses[1].ravel()])

    def robot_force(self, state: RobotState, rng: np.random.Generator | None = None) -> np.ndarray:
        """No generalized forces (the model's actuators and mocap bodies move the robot), but a recorded path's."""
        del rng
        force = np.zeros(self.robot_dofs())
        if self.loaded.spec.motion.robot == "recorded":
            drive = np.asarray(state.drive, dtype=float)
            force[: len(self.loaded.robot_joints)] = self._path_table(drive.tobytes(), drive).row(float(state.time))
        return force

    def batched_robot_force(self, drives: np.ndarray, times: np.ndarray) -> np.ndarray:
        """:meth:`robot_force` of many rows, drives (k, n_drive) and times (k,) s: shape (k, n_robot_dofs).

        Zero, but with ``robot = "recorded"`` the forces that keep the joints on the path over one
        command period (the control period in whole time steps, as a tree's propagation holds each
        command), looked up in each roll-out's :class:`~energy_margin.tasks.recorded_path.PathForceTable`.
        """
        times = np.asarray(times, dtype=float)
        forces = np.zeros((times.size, self.robot_dofs()))
        if self.loaded.spec.motion.robot != "recorded":
            return forces
        drives = np.asarray(drives, dtype=float)
        rows: dict[bytes, list[int]] = {}
        for row in range(times.size):
            rows.setdefault(drives[row].tobytes(), []).append(row)
        joints = len(self.loaded.robot_joints)
        for key, mine in rows.items():
            forces[mine, :joints] = self._path_table(key, drives[mine[0]]).at(times[mine])
        return forces

    def _path_table(self, key: bytes, drive: np.ndarray) -> PathForceTable:
        """The force table of the roll-out whose drive parameters are ``drive`` (``key``: their bytes), kept."""
        table = self._path_tables.get(key)
        if table is None:
            if len(self._path_tables) >= _PATH_TABLES:
                self._path_tables.clear()
            dt = self.config.timestep
            hold = control_steps(self.loaded.spec.motion.control_period, dt) or 1  # a scene file's period is a number
            table = PathForceTable.of(drive, n_joints=len(self.loaded.robot_joints), dt=dt, hold_steps=hold,
                                      armature=RECORDED_ARMATURE)  # fmt: skip
            self._path_tables[key] = table
        return table

    def model_command(self, drive: np.ndarray, time: float) -> ModelCommand | None:
        """The declared motion at ``time`` (s) times the trajectory's time scale ``drive[0]``."""
        motion = self.loaded.motion
        clock = time * float(drive[0])
        mocap = motion.mocap_at(clock)
        return ModelCommand(
            ctrl=motion.ctrl_at(clock),
            mocap_pos=None if mocap is None else mocap[0],
            mocap_quat=None if mocap is None else mocap[1],
        )

    def batched_model_command(self, drives: np.ndarray, times: np.ndarray) -> ModelCommand | None:
        """:meth:`model_command` of many rows at once, the same numbers to the last bit.

        Args:
            drives: each row's drive parameters, shape (k, n_drive).
            times: each row's time, shape (k,), s.

        Returns:
            A command whose arrays have a leading axis of k rows (controls (k, nu), mocap
            positions (k, nmocap, 3), quaternions (k, nmocap, 4)); ``None`` where a subclass
            commands its robot otherwise (its own model command, forces or servo targets, which
            are then evaluated row by row).

        """
        mine = type(self)
        if (mine.model_command, mine.robot_force, mine.robot_targets) != (
            SceneTask.model_command,
            SceneTask.robot_force,
            SceneTask.robot_targets,
        ):
            return None
        motion = self.loaded.motion
        clocks = np.asarray(times, dtype=float) * np.asarray(drives, dtype=float)[:, 0]
        mocap = motion.mocap_at_times(clocks)
        return ModelCommand(
            ctrl=motion.ctrl_at_times(clocks),
            mocap_pos=None if mocap is None else mocap[0],
            mocap_quat=None if mocap is None else mocap[1],
        )

    def wrench_limits(self, scene: Scene) -> WrenchLimits:
        """Forces m a and torques I alpha per axis, from the compiled model's masses and inertias.

        The mass and inertia of an axis include the armature of the object's joint along it (an
        object on slide joints with armature, like Gymnasium Pusher's puck: 8 mg body, 0.04 kg of
        armature per slide, is accelerated as the armature's mass); a joint without armature adds
        nothing, so objects with plain free joints keep ``m a`` and ``I alpha``.
        """
        loaded = self.loaded
        base_mass, base_inertia = loaded.object_inertials
        scale = scene.object_masses / base_mass
        inertia = base_inertia * scale[:, None]
        linear_armature, angular_armature = object_armature(loaded.model, self._index, loaded.n_objects)
        perturbation = loaded.perturbation
        limits = np.zeros((scene.n_objects, 6))
        limits[:, :3] = (scene.object_masses[:, None] + linear_armature) * np.asarray(perturbation.linear_acceleration)
        limits[:, 3:] = (inertia + angular_armature) * np.asarray(perturbation.angular_acceleration)
        if loaded.spec.object_joints == "upright":
            limits[:, 3:5] = 0.0
        return WrenchLimits(max_wrench=limits, max_duration=perturbation.max_duration)

    def _state_box(self) -> StateBox:
        """The scene file's ``[bounds]``; a side it leaves out is a box around the model (:data:`BOUNDS_MARGIN`)."""
        spec = self.loaded.spec
        low, high = spec.bounds_low, spec.bounds_high
        if low is None or high is None:
            around_low, around_high = box_around_model(self.loaded.model, BOUNDS_MARGIN)
            low = around_low if low is None else low
            high = around_high if high is None else high
        if any(a >= b for a, b in zip(low, high, strict=True)):
            raise spec.error(
                "bounds", f"leaves no room: low {list(low)} and high {list(high)} (one side from around the model)"
            )
        if spec.bounds_low is not None and spec.bounds_high is not None:
            source = "the scene file's [bounds]"
        else:
            source = f"[bounds] partly left out: a box {BOUNDS_MARGIN:g} m around the model's geoms"
        return StateBox(low=tuple(low), high=tuple(high), max_speed=spec.max_speed, source=source)  # type: ignore[arg-type]
