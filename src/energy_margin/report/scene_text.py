"""What a scene file declares, in words (the text of ``energy-margin scene``).

:func:`describe_scene` lists the objects with their masses, the actuators and mocap bodies, the
motion's duration, the sets and the wrench ranges; a value the file leaves out is marked as a
default or as derived.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import mujoco

from energy_margin.tasks.scene_layout import start_separation
from energy_margin.tasks.scene_spec import SceneSpec
from energy_margin.tasks.scene_task import SceneTask

__all__ = ["describe_scene"]

#: The perturbation bounds whose default is planar (tasks/scene_defaults.py).
_DEFAULT_BOUNDS = frozenset({"perturbation.linear_acceleration", "perturbation.angular_acceleration"})


def _region_text(table: Mapping[str, Any]) -> str:
    kind = table["type"]
    if kind in ("all", "any"):
        return f"{kind}(" + ", ".join(_region_text(part) for part in table["of"]) + ")"
    if kind == "not":
        return f"not({_region_text(table['region'])})"
    keys = ", ".join(f"{k}={_fmt(v)}" for k, v in table.items() if k != "type")
    return f"{kind}[{keys}]"


def _fmt(value: Any) -> str:
    if isinstance(value, tuple | list):
        return "(" + ", ".join(f"{v:g}" for v in value) + ")"
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def _given(spec: SceneSpec, key: str, text: str, source: str = "default") -> str:
    """``text``, followed by ``(source)`` when the file leaves ``key`` out (``SceneSpec.defaulted``)."""
    return f"{text} ({source})" if key in spec.defaulted else text


def _start_text(task: SceneTask) -> str:
    """``generate``'s object starts, each value marked when it is a default."""
    spec = task.loaded.spec
    start = spec.start
    if start.mode == "pile":
        where = f"pile, low {_fmt(start.low)} m, high {_fmt(start.high)} m"
    else:
        axes = []
        # A left-out axis keeps the start configuration's position: the initial keyframe's, else the model's.
        kept = "the initial keyframe's" if spec.motion.initial_keyframe is not None else "the model's"
        for axis in ("x", "y", "z", "yaw"):
            unit = "rad" if axis == "yaw" else "m"
            value = start.ranges.get(axis)
            shown = f"[{value[0]:g}, {value[1]:g}] {unit}" if value is not None else "0" if axis == "yaw" else kept
            axes.append(f"{axis} " + _given(spec, f"randomize.start.{axis}", shown))
        where = _given(spec, "randomize.start.mode", "ranges") + " " + ", ".join(axes)
    if start.min_separation is not None:
        separation = f"{start.min_separation:g} m"
    else:
        rule = start_separation(task.loaded)
        separation = f"{rule.distance:.3g} m, {rule.source}"
    return f"{where}, min separation " + _given(spec, "randomize.start.min_separation", separation)


def describe_scene(task: SceneTask) -> list[str]:
    """Lines that say what the scene file declares and what the model holds.

    A value the file leaves out is followed by ``(default)`` (or by where it comes from: the model,
    the last keyframe), and a derived perturbation value by ``(derived)``. The lines come in this
    order: the file and its model, the objects, the robot, the motion, the randomisation, the
    perturbation, the wrench bounds, the sets, the state box and the design parameters.
    """
    return [
        *_object_lines(task),
        *_robot_lines(task),
        *_motion_lines(task),
        _randomize_line(task),
        *_perturbation_lines(task),
        *_set_lines(task),
        _bounds_line(task),
        *_design_lines(task),
    ]


def _object_lines(task: SceneTask) -> list[str]:
    """The scene file, its model, and every object's mass, inertia, bounding radius and x-y footprint radius."""
    loaded = task.loaded
    spec = loaded.spec
    lines = [f"scene file {spec.path} (schema_version 1), model {spec.mjcf.name} (sha256 {loaded.model_sha256[:12]})"]
    joints_text = _given(spec, "objects.joints", str(spec.object_joints), "default: read from the model")
    lines.append(f"objects ({loaded.n_objects}, {joints_text}):")
    for index, name in enumerate(loaded.object_names):
        mass, inertias = loaded.object_inertials
        inertia = ", ".join(f"{v:.3g}" for v in inertias[index])
        lines.append(
            f"  {name}: mass {mass[index]:.4g} kg, inertia ({inertia}) kg m^2, "
            f"bounding radius {loaded.object_radius[index]:.3g} m, footprint radius in x-y "
            f"{loaded.object_footprint[index]:.3g} m"
        )
    return lines


def _robot_lines(task: SceneTask) -> list[str]:
    """The model's actuators, robot joints and mocap bodies."""
    loaded = task.loaded
    model = loaded.model
    lines = []
    actuators = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, i) or f"#{i}" for i in range(model.nu)]
    lines.append(f"actuators ({model.nu}): {', '.join(actuators) if actuators else 'none'}")
    mocap = [
        mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) for b in range(model.nbody) if model.body_mocapid[b] >= 0
    ]
    joints = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) or f"#{j}" for j in loaded.robot_joints]
    lines.append(f"robot joints ({len(joints)}): {', '.join(joints) if joints else 'none'}")
    lines.append(f"mocap bodies ({model.nmocap}): {', '.join(str(m) for m in mocap) if mocap else 'none'}")
    return lines


def _motion_lines(task: SceneTask) -> list[str]:
    """The motion's source, interpolation, duration, command period, start and driven actuators."""
    spec, model = task.loaded.spec, task.loaded.model
    lines = []
    motion = spec.motion
    source = (
        f"ctrl file {motion.ctrl_file.name}" if motion.ctrl_file is not None else f"{len(motion.keyframes)} keyframes"
    )
    duration = _given(spec, "motion.duration", f"{motion.duration:g} s", "default: the last keyframe's time")
    lines.append(
        f"motion: {source}, {_given(spec, 'motion.interpolation', motion.interpolation)} interpolation, "
        f"duration {duration} "
        f"({task.n_steps} steps of {model.opt.timestep:g} s), command every "
        f"{_given(spec, 'motion.control_period', f'{motion.control_period:g} s')} in analysis"
    )
    initial = motion.initial_keyframe or "the model's reference configuration"
    driven = ", ".join(motion.actuators) if motion.actuators is not None else "every actuator"
    robot = _given(spec, "motion.robot", motion.robot)
    if motion.robot == "recorded":
        robot += (
            f" (each roll-out's own joint path, {_given(spec, 'motion.path_points', str(motion.path_points))} knots)"
        )
    lines.append(
        f"  start {_given(spec, 'motion.initial_keyframe', initial)}, controls for "
        f"{_given(spec, 'motion.actuators', driven)}, robot during analysis {robot}"
    )
    return lines


def _randomize_line(task: SceneTask) -> str:
    """The ranges of the friction, mass and time scales, and the objects' starts."""
    spec = task.loaded.spec
    friction = f"{spec.friction_range[0]:g}-{spec.friction_range[1]:g}" if spec.friction_range else "the model's"
    mass_scale = f"{spec.mass_scale[0]:g}-{spec.mass_scale[1]:g}" if spec.mass_scale else "1"
    time_scale = f"{spec.time_scale[0]:g}-{spec.time_scale[1]:g}" if spec.time_scale else "1"
    return (
        f"randomize: friction {_given(spec, 'randomize.friction', friction)}, "
        f"mass scale {_given(spec, 'randomize.mass_scale', mass_scale)}, "
        f"time scale {_given(spec, 'randomize.time_scale', time_scale)}, start {_start_text(task)}"
    )


def _perturbation_lines(task: SceneTask) -> list[str]:
    """The perturbation's bounds, each marked default or derived, and the first object's wrench bounds."""
    loaded = task.loaded
    spec = loaded.spec
    lines = []
    perturbation = loaded.perturbation

    def bound(key: str, text: str) -> str:
        return _given(spec, f"perturbation.{key}", text, "derived" if key in perturbation.derived else "default")

    lines.append(
        "perturbation: linear acceleration "
        + bound("linear_acceleration", f"{_fmt(perturbation.linear_acceleration)} m/s^2")
        + ", angular acceleration "
        + bound("angular_acceleration", f"{_fmt(perturbation.angular_acceleration)} rad/s^2")
        + ", longest propagation "
        + bound("max_duration", f"{perturbation.max_duration:.3g} s")
        + ", lambda "
        + bound("lambda", f"{perturbation.likelihood_lambda:.3g} 1/J")
    )
    if not spec.derive_perturbation and _DEFAULT_BOUNDS & spec.defaulted:
        lines.append(
            "  the default bounds act in the world x-y plane with a torque about z (objects resting on a "
            "horizontal surface); set [perturbation] for other motions (docs/howto/scenes.md)"
        )
    for key, reason in perturbation.derived.items():
        lines.append(f"  derived perturbation.{key} (not in the file): {reason}")
    limits = task.wrench_limits(task.build_scene(loaded.n_objects, 0.5)).max_wrench
    lines.append(
        f"wrench bounds of {loaded.object_names[0]}: force {_fmt(tuple(limits[0, :3]))} N, "
        f"torque {_fmt(tuple(limits[0, 3:]))} N m"
    )
    return lines


def _set_lines(task: SceneTask) -> list[str]:
    """The capture and success sets: how many objects, in which region, and whether it follows the robot."""
    loaded = task.loaded
    spec = loaded.spec
    lines = []
    for name, table, at_least in (
        ("capture", spec.capture, spec.capture_at_least),
        ("success", spec.success, spec.success_at_least),
    ):
        who = _given(
            spec, f"{name}.at_least", f"at least {at_least} objects" if at_least is not None else "every object"
        )
        # Whether the region is built at every tree state's own robot pose, why, and whether by default.
        follow = loaded.follow.get(name)
        where = f"; {name} region {follow.describe()}" if follow is not None else ""
        lines.append(f"{name}: {who} in {_region_text(table)}{where}")
    return lines


def _bounds_line(task: SceneTask) -> str:
    """The state box the trees keep to."""
    spec = task.loaded.spec
    box = task.state_box
    around = "default: 1 m around the model's geoms"
    return (
        f"bounds: low {_given(spec, 'bounds.low', f'{_fmt(box.low)} m', around)}, "
        f"high {_given(spec, 'bounds.high', f'{_fmt(box.high)} m', around)}, "
        f"max speed {_given(spec, 'bounds.max_speed', f'{box.max_speed:g} m/s')}; trees reject states "
        "outside, and no frame outside becomes data"
    )


def _design_lines(task: SceneTask) -> list[str]:
    """The design parameters with their values and ranges."""
    loaded = task.loaded
    spec = loaded.spec
    lines = []
    for entry in spec.design:
        value = loaded.design_values.get(entry.name)
        # Without a default in the file, the value is the model's own (``scene`` applies no --set).
        shown = (
            _given(spec, f"{entry.key}.default", f"{value:g}", "default: the model's")
            if value is not None
            else _given(spec, f"{entry.key}.default", "the model's")
        )
        lines.append(
            f"design {entry.name} = {shown}: {entry.describe()}, range [{entry.low:g}, {entry.high:g}]"
            + (f" ({entry.doc})" if entry.doc else "")
        )
    return lines
