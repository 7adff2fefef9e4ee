"""A scene file's MuJoCo model: loaded and edited with ``mujoco.MjSpec``, compiled, its names checked.

:func:`load_scene` reads the scene file (:mod:`energy_margin.tasks.scene_file`), loads the model
it names, adds the copies of a template object body, compiles it and resolves every name the file
uses (object bodies, actuators, mocap bodies, sites, the initial keyframe) against the compiled
model. Each problem is one :class:`~energy_margin.errors.EnergyMarginError` line naming the scene
file, the key and the body, actuator or site.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from energy_margin.compat import compile_before_copying, copy_body
from energy_margin.errors import InvalidParameterError
from energy_margin.runs.npz import NpzError, read_npz
from energy_margin.sim.mujoco_index import object_geoms, object_inertials
from energy_margin.sim.mujoco_spec import model_hash
from energy_margin.tasks.model_file import is_binary_model, load_binary_model
from energy_margin.tasks.scene_defaults import PerturbationSettings, resolve_perturbation
from energy_margin.tasks.scene_file import DesignEntry, SceneSpec, read_scene_file, region_names
from energy_margin.tasks.scene_objects import (
    JOINT_KINDS,
    element_name,
    object_bodies,
    object_bounds,
    object_joint,
    object_joint_kind,
)

_SLIDE = mujoco.mjtJoint.mjJNT_SLIDE
_HINGE = mujoco.mjtJoint.mjJNT_HINGE


@dataclass(frozen=True)
class Motion:
    """The robot's motion as arrays (the model's actuators and mocap bodies).

    Attributes:
        ctrl_times: times of the control rows, shape (n_ctrl,), s (empty: no controls).
        ctrl: control rows for every actuator of the model, shape (n_ctrl, nu).
        mocap_times: times of the mocap rows, shape (n_mocap_rows,), s.
        mocap_pos: mocap positions, shape (n_mocap_rows, nmocap, 3), m (the model's own pose for a
            mocap body the file does not move).
        mocap_quat: mocap quaternions, shape (n_mocap_rows, nmocap, 4), (w, x, y, z).
        hold: zero-order hold instead of linear interpolation.

    """

    ctrl_times: np.ndarray
    ctrl: np.ndarray
    mocap_times: np.ndarray
    mocap_pos: np.ndarray
    mocap_quat: np.ndarray
    hold: bool

    def ctrl_at(self, time: float) -> np.ndarray | None:
        """Controls (nu,) at ``time`` (s), held at the ends; ``None`` without controls."""
        if self.ctrl_times.size == 0:
            return None
        return _interpolate(self.ctrl_times, self.ctrl, time, hold=self.hold)

    def mocap_at(self, time: float) -> tuple[np.ndarray, np.ndarray] | None:
        """Mocap positions (nmocap, 3) and unit quaternions (nmocap, 4) at ``time``; ``None`` without mocap."""
        if self.mocap_times.size == 0:
            return None
        pos = _interpolate(self.mocap_times, self.mocap_pos, time, hold=self.hold)
        quat = _interpolate_quat(self.mocap_times, self.mocap_quat, time, hold=self.hold)
        return pos, quat / np.linalg.norm(quat, axis=-1, keepdims=True)


def _interpolate(times: np.ndarray, values: np.ndarray, time: float, *, hold: bool) -> np.ndarray:
    """Values (n, ...) at ``time`` between rows at ``times`` (n,), held before the first and after the last."""
    if time <= times[0]:
        return values[0].copy()
    if time >= times[-1]:
        return values[-1].copy()
    upper = int(np.searchsorted(times, time, side="right"))
    lower = upper - 1
    if hold:
        return values[lower].copy()
    weight = (time - times[lower]) / (times[upper] - times[lower])
    result: np.ndarray = (1.0 - weight) * values[lower] + weight * values[upper]
    return result


#: Quaternions whose dot product exceeds this are interpolated linearly (then normalised): slerp's
#: weights divide by the sine of an angle that is then below about 1e-3 rad.
_NEARLY_EQUAL = 1.0 - 1e-6


def _interpolate_quat(times: np.ndarray, quats: np.ndarray, time: float, *, hold: bool) -> np.ndarray:
    """Unit quaternions (n, 4) at ``time`` between rows (n_rows, n, 4) at ``times``, along the shortest arc.

    q and -q are the same orientation: the row after is negated where its dot product with the row
    before is negative, so the interpolation never passes through zero. Nearly equal quaternions
    are interpolated linearly (normalised by the caller); the others by spherical linear
    interpolation.
    """
    if hold or time <= times[0] or time >= times[-1]:
        return _interpolate(times, quats, time, hold=hold)
    upper = int(np.searchsorted(times, time, side="right"))
    lower = upper - 1
    weight = (time - times[lower]) / (times[upper] - times[lower])
    start, end = quats[lower], quats[upper].copy()
    dot = np.sum(start * end, axis=-1)
    flip = dot < 0
    end[flip] = -end[flip]
    dot = np.clip(np.abs(dot), 0.0, 1.0)
    result: np.ndarray = (1.0 - weight) * start + weight * end
    arc = dot <= _NEARLY_EQUAL
    if np.any(arc):
        angle = np.arccos(dot[arc])[:, None]
        sine = np.sin(angle)
        result[arc] = (np.sin((1.0 - weight) * angle) * start[arc] + np.sin(weight * angle) * end[arc]) / sine
    return result


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

    @property
    def n_objects(self) -> int:
        """Number of objects."""
        return len(self.object_names)

    @cached_property
    def object_geoms(self) -> list[np.ndarray]:
        """The geom ids of each object's rigid subtree (its body and the bodies welded to it)."""
        return object_geoms(self.model, self.object_bodies)

    @cached_property
    def object_inertials(self) -> tuple[np.ndarray, np.ndarray]:
        """Mass (n,), kg, and diagonal inertia (n, 3), kg m^2, of each object's rigid subtree."""
        return object_inertials(self.model, self.object_bodies)


def _one_line(error: Exception) -> str:
    return " ".join(str(error).split())


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


_SPEC_ELEMENTS = {"body": "body", "geom": "geom", "site": "site", "joint": "joint", "actuator": "actuator"}


def _design_target(spec: SceneSpec, model_spec: mujoco.MjSpec, entry: DesignEntry) -> tuple[Any, float]:
    """The ``MjSpec`` element of a design parameter and the attribute's current value (checked)."""
    element = getattr(model_spec, _SPEC_ELEMENTS[entry.kind])(entry.element)
    if element is None:
        raise spec.error(f"{entry.key}.{entry.kind}", f"no {entry.kind} {entry.element!r} in {spec.mjcf.name}")
    value = getattr(element, entry.attribute, None)
    what = f"{entry.kind} {entry.element!r}"
    if isinstance(value, np.ndarray) and value.dtype.kind == "f" and value.ndim == 1 and value.size:
        if entry.index is None:
            if value.size > 1:
                raise spec.error(
                    entry.key,
                    f"{entry.attribute} of {what} holds {value.size} numbers: give index (0 to {value.size - 1})",
                )
            return element, float(value[0])
        if entry.index >= value.size:
            raise spec.error(
                f"{entry.key}.index",
                f"index {entry.index} is out of range: {entry.attribute} of {what} holds {value.size} numbers "
                f"(index 0 to {value.size - 1})",
            )
        return element, float(value[entry.index])
    if isinstance(value, float):
        if entry.index is not None:
            raise spec.error(f"{entry.key}.index", f"{entry.attribute} of {what} is one number: leave index out")
        return element, value
    if value is None and not hasattr(element, entry.attribute):
        raise spec.error(f"{entry.key}.attribute", f"{what} has no attribute {entry.attribute!r}")
    raise spec.error(
        f"{entry.key}.attribute",
        f"{entry.attribute} of {what} is not a real number or a list of them ({type(value).__name__})",
    )


#: A body's inertial attributes: MuJoCo reads them only when the body's inertial is explicit.
_INERTIAL = ("mass", "inertia", "ipos", "iquat", "fullinertia")


def _explicit_inertials(spec: SceneSpec, model_spec: mujoco.MjSpec) -> None:
    """Make the inertial of each body a design parameter sets explicit, as the compiled model has it.

    MuJoCo ignores a body's ``mass``, ``inertia`` and ``ipos`` unless its inertial is explicit (an
    ``<inertial>`` element), and otherwise derives them from its geoms. Each such body gets
    ``explicitinertial`` with the mass, principal inertia, centre of mass and axes of the model
    compiled before the design, so the parameter changes its own attribute only and its default
    (the model's own value) is the compiled one.
    """
    entries = [entry for entry in spec.design if entry.kind == "body" and entry.attribute in _INERTIAL]
    if not entries:
        return
    for entry in entries:
        if entry.attribute == "fullinertia":
            raise spec.error(
                f"{entry.key}.attribute", "fullinertia cannot be a design parameter: use inertia (principal moments)"
            )
    if model_spec.compiler.inertiafromgeom == mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_TRUE:
        entry = entries[0]
        raise spec.error(
            f"{entry.key}.attribute",
            f"{entry.attribute} of body {entry.element!r} cannot be set: the model computes every body's inertial "
            'from its geoms (compiler inertiafromgeom="true")',
        )
    try:
        compiled = model_spec.copy().compile()
    except (ValueError, mujoco.FatalError) as error:
        raise spec.error("mjcf", f"{spec.mjcf.name} does not compile: {_one_line(error)}") from None
    for entry in entries:
        body = model_spec.body(entry.element)
        index = mujoco.mj_name2id(compiled, mujoco.mjtObj.mjOBJ_BODY, entry.element)
        if body is None or index < 0:
            continue  # refused by name in _design_target
        if body.explicitinertial and np.isnan(body.fullinertia[0]):
            continue  # its own <inertial>: mass, inertia, ipos and iquat are what MuJoCo uses
        body.explicitinertial = True
        body.mass = float(compiled.body_mass[index])
        body.inertia = compiled.body_inertia[index].copy()
        body.ipos = compiled.body_ipos[index].copy()
        body.iquat = compiled.body_iquat[index].copy()
        body.fullinertia[0] = np.nan


def apply_design(
    spec: SceneSpec, model_spec: mujoco.MjSpec, design: Mapping[str, Any] | None = None
) -> dict[str, float]:
    """Set every ``[design]`` parameter of ``spec`` on ``model_spec``; the values set, by name.

    A parameter takes its value in ``design``, else its ``default``, else keeps the model's own.

    Raises:
        InvalidParameterError: ``design`` names a parameter the file does not declare.
        EnergyMarginError: an element or attribute the model does not have, an index out of range,
            a value that is not a number or lies outside the parameter's range (``FILE:LINE: design.NAME``).

    """
    design = dict(design or {})
    declared = {entry.name for entry in spec.design}
    unknown = sorted(set(design) - declared)
    if unknown:
        names = ", ".join(sorted(declared)) or "none"
        raise InvalidParameterError(
            "design",
            f"names unknown scene configuration keys: {', '.join(unknown)} "
            f"(the [design] parameters of {spec.path}: {names})",
        )
    _explicit_inertials(spec, model_spec)
    values: dict[str, float] = {}
    for entry in spec.design:
        element, current = _design_target(spec, model_spec, entry)
        value = design.get(entry.name, entry.default if entry.default is not None else current)
        if isinstance(value, bool) or not isinstance(value, int | float) or not np.isfinite(value):
            raise spec.error(entry.key, f"{entry.name} must be a finite number, got {value!r}")
        if not entry.low <= value <= entry.high:
            given = "given" if entry.name in design else "the model's" if entry.default is None else "default"
            raise spec.error(
                entry.key, f"{entry.name} = {value:g} ({given}) lies outside its range [{entry.low:g}, {entry.high:g}]"
            )
        if entry.index is None:
            if isinstance(getattr(element, entry.attribute), float):
                setattr(element, entry.attribute, float(value))
            else:
                getattr(element, entry.attribute)[0] = float(value)
        else:
            getattr(element, entry.attribute)[entry.index] = float(value)
        values[entry.name] = float(value)
    return values


def _check_file(spec: SceneSpec, key: str, path: Path, what: str = "") -> None:
    """Refuse a ``path`` (named by ``key``) that is not a readable regular file."""
    try:
        if path.is_file():
            return
        problem = "is not a file" if path.exists() else "does not exist"
    except OSError as error:
        problem = f"cannot be read ({error.strerror})"
    raise spec.error(key, f"{what}{path} {problem}")


def _motion(spec: SceneSpec, model: mujoco.MjModel) -> Motion:
    motion = spec.motion
    nu = int(model.nu)
    columns = np.arange(nu)
    if motion.actuators is not None:
        columns = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, name) for name in motion.actuators])
        for name, index in zip(motion.actuators, columns, strict=True):
            if index < 0:
                raise spec.error("motion.actuators", f"no actuator {name!r} in {spec.mjcf.name}")
    width = int(columns.size)
    what = (
        f"{width} actuators in motion.actuators"
        if motion.actuators is not None
        else f"{nu} actuators in {spec.mjcf.name}"
    )
    if motion.ctrl_file is not None:
        times, ctrl = _read_ctrl_file(spec, width, what)
    else:
        rows = [k for k in motion.keyframes if k.ctrl is not None]
        times = np.array([k.time for k in rows])
        for keyframe in rows:
            if len(keyframe.ctrl or ()) != width:
                raise spec.error(f"{keyframe.key}.ctrl", f"has {len(keyframe.ctrl or ())} values for the {what}")
        ctrl = np.array([k.ctrl for k in rows], dtype=float) if rows else np.zeros((0, width))
    full = np.zeros((ctrl.shape[0], nu))
    full[:, columns] = ctrl
    ctrl = full
    mocap_rows = [k for k in motion.keyframes if k.mocap]
    nmocap = int(model.nmocap)
    # The model's own mocap poses, in mocap-index order (a mocap body is a child of the world).
    mocap_bodies = np.flatnonzero(model.body_mocapid >= 0)
    mocap_bodies = mocap_bodies[np.argsort(model.body_mocapid[mocap_bodies])]
    default_pos, default_quat = model.body_pos[mocap_bodies], model.body_quat[mocap_bodies]
    mocap_pos = np.tile(default_pos, (len(mocap_rows), 1, 1)).reshape(len(mocap_rows), nmocap, 3)
    mocap_quat = np.tile(default_quat, (len(mocap_rows), 1, 1)).reshape(len(mocap_rows), nmocap, 4)
    for row, keyframe in enumerate(mocap_rows):
        for body_name, (pos, quat) in keyframe.mocap.items():
            body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body_name)
            key = f"{keyframe.key}.mocap.{body_name}"
            if body < 0:
                raise spec.error(key, f"no body {body_name!r} in {spec.mjcf.name}")
            mocap_id = int(model.body_mocapid[body])
            if mocap_id < 0:
                raise spec.error(key, f'body {body_name!r} in {spec.mjcf.name} is not a mocap body (mocap="true")')
            mocap_pos[row, mocap_id] = pos
            if quat is not None:
                mocap_quat[row, mocap_id] = np.asarray(quat) / np.linalg.norm(quat)
    mocap_times = np.array([k.time for k in mocap_rows])
    return Motion(times, ctrl, mocap_times, mocap_pos, mocap_quat, motion.interpolation == "hold")


def _read_ctrl_file(spec: SceneSpec, nu: int, what: str) -> tuple[np.ndarray, np.ndarray]:
    path = spec.motion.ctrl_file
    assert path is not None
    key = "motion.ctrl_file"
    _check_file(spec, key, path)
    try:
        archive = read_npz(path)
    except NpzError as error:
        raise spec.error(key, f"{path.name} is not a readable .npz file ({error})") from None
    missing = [name for name in ("time", "ctrl") if name not in archive]
    if missing:
        raise spec.error(key, f"{path.name} has no array {missing[0]!r} (it needs time (n,) and ctrl (n, nu))")
    for name in ("time", "ctrl"):
        if archive[name].dtype.kind not in "fiu":
            raise spec.error(key, f"{path.name}: {name} must hold numbers, got {archive[name].dtype}")
    times = archive["time"].astype(float)
    ctrl = archive["ctrl"].astype(float)
    if times.ndim != 1 or times.size == 0 or not np.all(np.isfinite(times)):
        raise spec.error(key, f"{path.name}: time must be a non-empty 1-d array of finite seconds")
    if np.any(np.diff(times) <= 0):
        row = int(np.flatnonzero(np.diff(times) <= 0)[0]) + 1
        raise spec.error(key, f"{path.name}: time is not increasing (row {row})")
    if ctrl.ndim != 2 or ctrl.shape[0] != times.size or ctrl.shape[1] != nu:
        raise spec.error(
            key,
            f"{path.name}: ctrl has shape {ctrl.shape}, expected ({times.size}, {nu}) for the {what}",
        )
    if not np.all(np.isfinite(ctrl)):
        raise spec.error(key, f"{path.name}: ctrl holds NaN or infinite values")
    return times, ctrl


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
    )
