"""A scene file's MuJoCo model: loaded and edited with ``mujoco.MjSpec``, compiled, its names checked.

:func:`load_scene` reads the scene file (:mod:`energy_margin.tasks.scene_file`), loads the model
it names, adds the copies of a template object body, compiles it and resolves every name the file
uses (object bodies, actuators, mocap bodies, sites, the initial keyframe) against the compiled
model. Each problem is one :class:`~energy_margin.errors.EnergyMarginError` line naming the scene
file, the key and the body, actuator or site.

The ``[design]`` parameters are set by :mod:`~energy_margin.tasks.scene_design` and the motion's
arrays made by :mod:`~energy_margin.tasks.scene_motion`.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from energy_margin.compat import compile_before_copying, copy_body
from energy_margin.sim.mujoco_index import object_geoms, object_inertials
from energy_margin.sim.mujoco_spec import model_hash
from energy_margin.tasks.model_file import is_binary_model, load_binary_model
from energy_margin.tasks.scene_defaults import PerturbationSettings, resolve_perturbation
from energy_margin.tasks.scene_design import (
    _design_target,
    _one_line,
    apply_design,
)
from energy_margin.tasks.scene_file import read_scene_file
from energy_margin.tasks.scene_follow import RegionFollow, region_follow
from energy_margin.tasks.scene_motion import (
    Motion,
    _check_file,
    _motion,
)
from energy_margin.tasks.scene_objects import (
    JOINT_KINDS,
    element_name,
    object_bodies,
    object_bounds,
    object_footprints,
    object_joint,
    object_joint_kind,
)
from energy_margin.tasks.scene_sections import region_names
from energy_margin.tasks.scene_spec import SceneSpec

__all__ = [
    "LoadedScene",
    "Motion",
    "apply_design",
    "compile_spec",
    "load_scene",
    "load_scene_cached",
    "model_hash",
    "resolve_scene",
]

_SLIDE = mujoco.mjtJoint.mjJNT_SLIDE
_HINGE = mujoco.mjtJoint.mjJNT_HINGE


@dataclass(frozen=True)
class LoadedScene:
    """A scene file with its compiled model and resolved names.

    Attributes:
        spec: the validated scene file.
        model: the compiled model (templates copied); treat as read-only.
        model_sha256: SHA-256 of the compiled model in MuJoCo's binary format.
        object_bodies: body id of each object, shape (n_objects,).
        object_names: body name of each object.
        object_joints: joint id of each object's free joint (or first upright joint).
        robot_joints: ids of the hinge and slide joints that belong to no object.
        object_radius: bounding radius of each object about its body origin, shape (n_objects,), m.
        object_half_extents: half extents of each object's bounding box in its body frame, (n_objects, 3), m.
        motion: the robot's motion.
        initial_qpos: the model's start configuration (its reference or the initial keyframe), (nq,).
        perturbation: the perturbation settings, the file's or derived from the scene where it has none.
        design_values: the value of every ``[design]`` parameter the model was compiled with
            (overrides, else each one's default, else the model's own value).
        follow: ``"capture"`` and ``"success"`` -> whether that region follows the robot and why
            (``spec.capture_follows`` and ``spec.success_follows`` hold the resolved values).

    """

    spec: SceneSpec
    model: mujoco.MjModel
    model_sha256: str
    object_bodies: np.ndarray
    object_names: tuple[str, ...]
    object_joints: tuple[int, ...]
    robot_joints: tuple[int, ...]
    object_radius: np.ndarray
    object_half_extents: np.ndarray
    motion: Motion
    initial_qpos: np.ndarray
    perturbation: PerturbationSettings
    design_values: dict[str, float] = field(default_factory=dict)
    follow: dict[str, RegionFollow] = field(default_factory=dict)

    @property
    def n_objects(self) -> int:
        """Number of objects."""
        return len(self.object_names)

    @cached_property
    def object_geoms(self) -> list[np.ndarray]:
        """The geom ids of each object's rigid subtree (its body and the bodies welded to it)."""
        return object_geoms(self.model, self.object_bodies)

    @cached_property
    def object_footprint(self) -> np.ndarray:
        """Footprint radius of each object in the world x-y plane at :attr:`initial_qpos`, (n,), m.

        See :func:`~energy_margin.tasks.scene_objects.object_footprints`; never above the bounding radius.
        """
        footprint = object_footprints(self.model, self.object_bodies, self.initial_qpos)
        return np.minimum(footprint, self.object_radius)

    @cached_property
    def object_inertials(self) -> tuple[np.ndarray, np.ndarray]:
        """Mass (n,), kg, and diagonal inertia (n, 3), kg m^2, of each object's rigid subtree."""
        return object_inertials(self.model, self.object_bodies)


_name = element_name


def compile_spec(spec: SceneSpec, design: Mapping[str, Any] | None = None) -> tuple[mujoco.MjSpec, mujoco.MjModel]:
    """Load the scene's MJCF with ``MjSpec``, add the template copies, apply the design and compile it.

    Args:
        spec: the validated scene file.
        design: values of some of its ``[design]`` parameters; the others take their defaults
            (:func:`apply_design`).

    """
    _check_file(spec, "mjcf", spec.mjcf, "model file ")
    if is_binary_model(spec.mjcf):
        raise spec.error("mjcf", f"{spec.mjcf.name} is a compiled model (.mjb): it has no MJCF to edit")
    try:
        model_spec = mujoco.MjSpec.from_file(str(spec.mjcf))
    except (ValueError, mujoco.FatalError) as error:
        raise spec.error("mjcf", f"{spec.mjcf.name} cannot be loaded: {_one_line(error)}") from None
    if spec.template is not None:
        template = model_spec.body(spec.template)
        if template is None:
            raise spec.error("objects.template", f"no body {spec.template!r} in {spec.mjcf.name}")
        # The worldbody is compared first: MuJoCo before 3.14 crashes on the worldbody's parent.
        worldbody = model_spec.worldbody.name
        if template.name == worldbody or template.parent is None or template.parent.name != worldbody:
            raise spec.error("objects.template", f"body {spec.template!r} must be a child of the worldbody")
        try:
            probe = compile_before_copying(model_spec)
        except (ValueError, mujoco.FatalError) as error:
            raise spec.error("mjcf", f"{spec.mjcf.name} does not compile: {_one_line(error)}") from None
        body = mujoco.mj_name2id(probe, mujoco.mjtObj.mjOBJ_BODY, spec.template)
        geoms = np.flatnonzero(probe.geom_bodyid == body)
        radius = (
            float(np.max(np.linalg.norm(probe.geom_pos[geoms], axis=1) + probe.geom_rbound[geoms]))
            if geoms.size
            else 0.05
        )
        # Free copies start side by side along x; upright copies keep the template's zero origin
        # (their slide joints measure world positions from it) and take their places from the start draw.
        kind = spec.object_joints or object_joint_kind(probe, [body])
        spacing = 2.0 * radius + 0.01 if kind == "free" else 0.0
        model_spec.copy_during_attach = True
        count = spec.count or 0
        try:
            copy_body(
                model_spec,
                template,
                [(index * spacing, 0.0, 0.0) for index in range(count)],
                [f"_{index}" for index in range(count)],
            )
        except (ValueError, mujoco.FatalError) as error:
            raise spec.error("objects.template", f"cannot copy body {spec.template!r}: {_one_line(error)}") from None
    apply_design(spec, model_spec, design)
    try:
        model = model_spec.compile()
    except (ValueError, mujoco.FatalError) as error:
        raise spec.error("mjcf", f"{spec.mjcf.name} does not compile: {_one_line(error)}") from None
    return model_spec, model


def _check_region_names(spec: SceneSpec, model: mujoco.MjModel) -> None:
    kinds = {"body": mujoco.mjtObj.mjOBJ_BODY, "site": mujoco.mjtObj.mjOBJ_SITE, "geom": mujoco.mjtObj.mjOBJ_GEOM}
    for set_name, table in (("capture", spec.capture), ("success", spec.success)):
        for kind, name, key in region_names(table, f"{set_name}.region"):
            if mujoco.mj_name2id(model, kinds[kind], name) < 0:
                raise spec.error(key, f"no {kind} {name!r} in {spec.mjcf.name}")


def load_scene(path: Path | str, design: Mapping[str, Any] | None = None) -> LoadedScene:
    """Read the scene file at ``path``, compile its model with ``design`` (:func:`apply_design`), resolve its names.

    A model file ending in ``.mjb`` is loaded as compiled (:func:`~energy_margin.tasks.model_file.load_binary_model`).
    """
    spec = read_scene_file(path)
    if is_binary_model(spec.mjcf):  # compiled already: no template or [design] (load_binary_model)
        _check_file(spec, "mjcf", spec.mjcf, "model file ")
        model = load_binary_model(spec)
        apply_design(spec, mujoco.MjSpec(), design)  # no parameters: refuses any design value given
        return resolve_scene(spec, model)
    model_spec, model = compile_spec(spec, design)
    values = {entry.name: _design_target(spec, model_spec, entry)[1] for entry in spec.design}
    return resolve_scene(spec, model, design_values=values)


def resolve_scene(
    spec: SceneSpec, model: mujoco.MjModel, *, design_values: Mapping[str, float] | None = None
) -> LoadedScene:
    """Resolve a validated scene's names against its compiled ``model`` (not copied).

    ``design_values``: the ``[design]`` values ``model`` was compiled with (recorded, not applied).
    """
    bodies = object_bodies(spec, model)
    if spec.object_joints is None:
        # The kind of the objects' joints is read from the model unless the file declares it.
        spec = replace(spec, object_joints=object_joint_kind(model, bodies))  # type: ignore[arg-type]
    joints = [object_joint(spec, model, body) for body in bodies]
    if spec.capture_at_least is not None and spec.capture_at_least > len(bodies):
        raise spec.error("capture.at_least", f"is {spec.capture_at_least} but the scene has {len(bodies)} objects")
    if spec.success_at_least is not None and spec.success_at_least > len(bodies):
        raise spec.error("success.at_least", f"is {spec.success_at_least} but the scene has {len(bodies)} objects")
    object_joint_ids: set[int] = set()
    for body in bodies:
        first, count = int(model.body_jntadr[body]), int(model.body_jntnum[body])
        object_joint_ids.update(range(first, first + count))
    robot = []
    for joint in range(model.njnt):
        if joint in object_joint_ids:
            continue
        kind = int(model.jnt_type[joint])
        if kind not in (int(_SLIDE), int(_HINGE)):
            body_name = _name(model, mujoco.mjtObj.mjOBJ_BODY, int(model.jnt_bodyid[joint]))
            raise spec.error(
                "objects",
                f"body {body_name!r} in {spec.mjcf.name} has a {JOINT_KINDS.get(kind, '?')} joint but is not an "
                "object: add it to objects.bodies (robot joints must be hinges or slides)",
            )
        robot.append(joint)
    _check_region_names(spec, model)
    # A follow the file leaves out is resolved here: true where the region rides on a body the robot moves.
    follow = {
        name: region_follow(
            name,
            table,
            None if f"{name}.follow" in spec.defaulted else stated,
            model,
            robot,
            object_joints=object_joint_ids,
        )
        for name, table, stated in (
            ("capture", spec.capture, spec.capture_follows),
            ("success", spec.success, spec.success_follows),
        )
    }
    spec = replace(spec, capture_follows=follow["capture"].follows, success_follows=follow["success"].follows)
    motion = _motion(spec, model)
    initial: np.ndarray = np.array(model.qpos0, dtype=float)
    if spec.motion.initial_keyframe is not None:
        key = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, spec.motion.initial_keyframe)
        if key < 0:
            raise spec.error(
                "motion.initial_keyframe", f"no keyframe {spec.motion.initial_keyframe!r} in {spec.mjcf.name}"
            )
        initial = np.array(model.key_qpos[key], dtype=float)
    radius, extents = object_bounds(spec, model, bodies)
    names = tuple(_name(model, mujoco.mjtObj.mjOBJ_BODY, body) for body in bodies)
    return LoadedScene(
        spec=spec,
        model=model,
        model_sha256=model_hash(model),
        object_bodies=np.array(bodies, dtype=int),
        object_names=names,
        object_joints=tuple(joints),
        robot_joints=tuple(robot),
        object_radius=radius,
        object_half_extents=extents,
        motion=motion,
        initial_qpos=initial,
        perturbation=resolve_perturbation(spec, model, np.array(bodies, dtype=int)),
        design_values=dict(design_values or {}),
        follow=follow,
    )


_LOADED: dict[tuple[str, int, int, str], LoadedScene] = {}


def load_scene_cached(path: Path, design: Mapping[str, Any] | None = None) -> LoadedScene:
    """Load a scene file once per (path, modification times of the file and its model, design values)."""
    design = dict(design or {})
    try:
        scene_time = path.stat().st_mtime_ns
        design_key = json.dumps(design, sort_keys=True)
    except (OSError, TypeError, ValueError):
        return load_scene(path, design)
    loaded = None
    for key, value in _LOADED.items():
        if key[0] == str(path) and key[1] == scene_time and key[3] == design_key:
            try:
                if value.spec.mjcf.stat().st_mtime_ns == key[2]:
                    loaded = value
            except OSError:
                pass
    if loaded is None:
        loaded = load_scene(path, design)
        model_time = loaded.spec.mjcf.stat().st_mtime_ns
        if len(_LOADED) > 8:
            _LOADED.clear()
        _LOADED[(str(path), scene_time, model_time, design_key)] = loaded
    return loaded
