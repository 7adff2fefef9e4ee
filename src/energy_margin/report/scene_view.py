"""What a scene file declares, in words and as a picture (``energy-margin scene``).

:func:`describe_scene` lists the objects with their masses, the actuators and mocap bodies, the
motion's duration, the sets and the wrench ranges. :func:`render_scene` draws the scene at t = 0
(the first start ``generate --seed 0`` would use) with MuJoCo's own renderer, the capture set in
translucent blue and the success set in translucent green, added as visual-only geoms to a copy of
the model edited with ``MjSpec`` (over a compiled ``.mjb`` model, drawn from a model of their own).
"""

from __future__ import annotations

import copy
import os
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from energy_margin.compat import copy_light
from energy_margin.errors import EnergyMarginError, InvalidParameterError
from energy_margin.report.render import View, fit_view
from energy_margin.runs.files import staging_directory
from energy_margin.sim.base import CompiledModel, require
from energy_margin.tasks.model_file import is_binary_model
from energy_margin.tasks.scene_model import compile_spec
from energy_margin.tasks.scene_spec import SceneSpec
from energy_margin.tasks.scene_task import SceneTask
from energy_margin.world.state import FrameState

__all__ = ["describe_scene", "framed_view", "parse_camera", "render_scene", "start_frame"]

_CAPTURE_RGBA = (0.12, 0.47, 0.71, 0.3)
_SUCCESS_RGBA = (0.2, 0.63, 0.17, 0.3)
_EXCLUDED_RGBA = (0.9, 0.1, 0.1, 0.25)
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
        for axis in ("x", "y", "z", "yaw"):
            unit = "rad" if axis == "yaw" else "m"
            value = start.ranges.get(axis)
            shown = (
                f"[{value[0]:g}, {value[1]:g}] {unit}" if value is not None else "0" if axis == "yaw" else "the model's"
            )
            axes.append(f"{axis} " + _given(spec, f"randomize.start.{axis}", shown))
        where = _given(spec, "randomize.start.mode", "ranges") + " " + ", ".join(axes)
    if start.min_separation is not None:
        separation = f"{start.min_separation:g} m"
    else:
        separation = f"{2.0 * float(np.max(task.loaded.object_radius)):.3g} m, twice the largest bounding radius"
    return f"{where}, min separation " + _given(spec, "randomize.start.min_separation", separation)


def describe_scene(task: SceneTask) -> list[str]:
    """Lines that say what the scene file declares and what the model holds.

    A value the file leaves out is followed by ``(default)`` (or by where it comes from: the model,
    the last keyframe), and a derived perturbation value by ``(derived)``.
    """
    loaded = task.loaded
    spec, model = loaded.spec, loaded.model
    lines = [f"scene file {spec.path} (schema_version 1), model {spec.mjcf.name} (sha256 {loaded.model_sha256[:12]})"]
    joints_text = _given(spec, "objects.joints", str(spec.object_joints), "default: read from the model")
    lines.append(f"objects ({loaded.n_objects}, {joints_text}):")
    for index, name in enumerate(loaded.object_names):
        mass, inertias = loaded.object_inertials
        inertia = ", ".join(f"{v:.3g}" for v in inertias[index])
        lines.append(
            f"  {name}: mass {mass[index]:.4g} kg, inertia ({inertia}) kg m^2, "
            f"bounding radius {loaded.object_radius[index]:.3g} m"
        )
    actuators = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, i) or f"#{i}" for i in range(model.nu)]
    lines.append(f"actuators ({model.nu}): {', '.join(actuators) if actuators else 'none'}")
    mocap = [
        mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) for b in range(model.nbody) if model.body_mocapid[b] >= 0
    ]
    joints = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) or f"#{j}" for j in loaded.robot_joints]
    lines.append(f"robot joints ({len(joints)}): {', '.join(joints) if joints else 'none'}")
    lines.append(f"mocap bodies ({model.nmocap}): {', '.join(str(m) for m in mocap) if mocap else 'none'}")
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
    lines.append(
        f"  start {_given(spec, 'motion.initial_keyframe', initial)}, controls for "
        f"{_given(spec, 'motion.actuators', driven)}, "
        f"robot during analysis {_given(spec, 'motion.robot', motion.robot)}"
    )
    friction = f"{spec.friction_range[0]:g}-{spec.friction_range[1]:g}" if spec.friction_range else "the model's"
    mass_scale = f"{spec.mass_scale[0]:g}-{spec.mass_scale[1]:g}" if spec.mass_scale else "1"
    time_scale = f"{spec.time_scale[0]:g}-{spec.time_scale[1]:g}" if spec.time_scale else "1"
    lines.append(
        f"randomize: friction {_given(spec, 'randomize.friction', friction)}, "
        f"mass scale {_given(spec, 'randomize.mass_scale', mass_scale)}, "
        f"time scale {_given(spec, 'randomize.time_scale', time_scale)}, start {_start_text(task)}"
    )
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
    for name, table, at_least in (
        ("capture", spec.capture, spec.capture_at_least),
        ("success", spec.success, spec.success_at_least),
    ):
        who = _given(
            spec, f"{name}.at_least", f"at least {at_least} objects" if at_least is not None else "every object"
        )
        if name == "success":
            where = ""
        elif spec.capture_follows:
            where = " (built at every tree node's own robot pose: capture.follow)"
        else:
            where = ", " + _given(spec, "capture.follow", "built at the analysed frame")
        lines.append(f"{name}: {who} in {_region_text(table)}{where}")
    box = task.state_box
    around = "default: 1 m around the model's geoms"
    lines.append(
        f"bounds: low {_given(spec, 'bounds.low', f'{_fmt(box.low)} m', around)}, "
        f"high {_given(spec, 'bounds.high', f'{_fmt(box.high)} m', around)}, "
        f"max speed {_given(spec, 'bounds.max_speed', f'{box.max_speed:g} m/s')}; trees reject states "
        "outside, and no frame outside becomes data"
    )
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


def start_frame(task: SceneTask, seed: int = 0) -> FrameState:
    """The first start ``generate --seed SEED`` draws (trajectory 0).

    Raises:
        EnergyMarginError: the scene file's start ranges hold no layout (the message of
            ``generate``, in one line).
    """
    child = np.random.SeedSequence(seed).spawn(1)[0]
    try:
        return task.sample_trajectory(np.random.default_rng(child), task.loaded.n_objects).initial
    except ValueError as error:
        raise EnergyMarginError(f"cannot draw the scene's start: {error}") from None


def _corners(centre: np.ndarray, rotation: np.ndarray, half: np.ndarray) -> np.ndarray:
    """The 8 corners (8, 3) of a box of half sizes ``half`` (3,) at ``centre`` rotated by ``rotation``."""
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
    return np.asarray(centre + (signs * half) @ rotation.T, dtype=float)


def _add_region_geoms(
    spec: mujoco.MjSpec,
    table: Mapping[str, Any],
    lookup: Any,
    rgba: tuple[float, ...],
    extent: float,
    bounds: list[np.ndarray] | None = None,
) -> None:
    """Add a region's shapes to ``spec``; append the corners of the bounded ones to ``bounds`` (m)."""
    bounds = [] if bounds is None else bounds
    kind = table["type"]
    if kind in ("all", "any"):
        for part in table["of"]:
            _add_region_geoms(spec, part, lookup, rgba, extent, bounds)
        return
    if kind == "not":
        _add_region_geoms(spec, table["region"], lookup, _EXCLUDED_RGBA, extent, bounds)
        return
    origin, rotation = np.zeros(3), np.eye(3)
    for frame_kind in ("body", "site"):
        if frame_kind in table and kind in ("box", "cylinder"):
            origin, rotation = lookup(frame_kind, table[frame_kind])
    quat = np.empty(4)
    mujoco.mju_mat2Quat(quat, rotation.ravel())
    common = {"contype": 0, "conaffinity": 0, "group": 0, "rgba": list(rgba)}
    if kind == "box":
        pos = origin + rotation @ np.asarray(table["center"])
        spec.worldbody.add_geom(
            type=mujoco.mjtGeom.mjGEOM_BOX, size=list(table["half_size"]), pos=pos, quat=quat, **common
        )
        bounds.append(_corners(pos, rotation, np.asarray(table["half_size"], dtype=float)))
    elif kind == "cylinder":
        pos = origin + rotation @ np.asarray(table["center"])
        size = [table["radius"], table["half_height"], 0.0]
        spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=size, pos=pos, quat=quat, **common)
        half = np.array([table["radius"], table["radius"], table["half_height"]], dtype=float)
        bounds.append(_corners(pos, rotation, half))
    elif kind == "distance":
        point = lookup("site" if "site" in table else "body", table.get("site", table.get("body")))[0]
        spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[table["max"], 0, 0], pos=point, **common)
        bounds.append(_corners(np.asarray(point, dtype=float), np.eye(3), np.full(3, float(table["max"]))))
    elif kind == "height":
        reference = float(lookup("body", table["body"])[0][2]) if "body" in table else float(table.get("plane", 0.0))
        # Thin sheets at the bounds: a solid slab would hide the scene.
        levels = [reference + float(table.get("min", 0.0))]
        if "max" in table:
            levels.append(reference + float(table["max"]))
        sheet = {**common, "rgba": [rgba[0], rgba[1], rgba[2], 0.06]}
        for level in levels:
            spec.worldbody.add_geom(
                type=mujoco.mjtGeom.mjGEOM_BOX, size=[extent, extent, 0.0005], pos=[0.0, 0.0, level + 0.001], **sheet
            )


def _gl_context(width: int, height: int) -> Any:
    """An OpenGL context: on Linux EGL (headless) unless MUJOCO_GL asks for OSMesa or, with a display, GLFW."""
    if sys.platform.startswith("linux"):
        choice = os.environ.get("MUJOCO_GL", "").lower()
        if choice == "osmesa":
            from mujoco.osmesa import GLContext as OSMesaContext

            return OSMesaContext(width, height)
        if not (choice in ("glfw", "glx") and os.environ.get("DISPLAY")):
            from mujoco.egl import GLContext as EGLContext

            return EGLContext(width, height)
    return mujoco.GLContext(width, height)


def _add_lights(model: mujoco.MjModel, data: mujoco.MjData, camera: mujoco.MjvCamera, scene: mujoco.MjvScene) -> None:
    """Append the lights of ``model`` (not its headlight) to ``scene``, as far as it has room."""
    own = mujoco.MjvScene(model, maxgeom=max(int(model.ngeom), 1))
    mujoco.mjv_updateScene(model, data, mujoco.MjvOption(), None, camera, mujoco.mjtCatBit.mjCAT_ALL, own)
    for index in range(own.nlight):
        light = own.lights[index]
        if light.headlight or scene.nlight >= len(scene.lights):
            continue
        target = scene.lights[scene.nlight]
        copy_light(light, target)
        target.headlight = 0
        scene.nlight += 1


def _render(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    camera: mujoco.MjvCamera,
    width: int,
    height: int,
    overlay: tuple[mujoco.MjModel, mujoco.MjData] | None = None,
) -> np.ndarray:
    """RGB pixels (height, width, 3) of ``data`` seen from ``camera`` with MuJoCo's renderer.

    ``overlay``: a second model and its data whose geoms are drawn in the same scene.
    """
    context = _gl_context(width, height)
    context.make_current()
    try:
        scene = mujoco.MjvScene(model, maxgeom=10_000)
        options = mujoco.MjvOption()
        mujoco.mjv_updateScene(model, data, options, None, camera, mujoco.mjtCatBit.mjCAT_ALL, scene)
        if overlay is not None:
            mujoco.mjv_addGeoms(*overlay, options, mujoco.MjvPerturb(), mujoco.mjtCatBit.mjCAT_ALL, scene)
            _add_lights(*overlay, camera, scene)
        render_context = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_100)
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, render_context)
        viewport = mujoco.MjrRect(0, 0, width, height)
        mujoco.mjr_render(viewport, scene, render_context)
        pixels = np.empty((height, width, 3), dtype=np.uint8)
        mujoco.mjr_readPixels(pixels, None, viewport, render_context)
        render_context.free()
    finally:
        context.free()
    return np.flipud(pixels)


#: The picture's default heading and pitch, degrees.
DEFAULT_AZIMUTH, DEFAULT_ELEVATION = 135.0, -60.0


def framed_view(
    object_pos: np.ndarray,
    object_radius: np.ndarray,
    region_bounds: list[np.ndarray],
    *,
    camera: tuple[float, ...] | None = None,
) -> View:
    """The picture's camera: framing the objects and the bounded regions, whatever else the model holds.

    A robot arm's base, its links and the floor are left out of the framing: a third-party arm's
    model spans metres while its objects span centimetres.

    Args:
        object_pos: object origins, shape (n, 3), m.
        object_radius: their bounding radii, shape (n,), m.
        region_bounds: corner points of the bounded capture and success regions, each (m, 3), m
            (height bounds have none).
        camera: ``(azimuth, elevation)`` in degrees, or ``(azimuth, elevation, distance)`` with
            the distance in m, overriding the fitted one (``--camera``); ``None`` for the defaults.

    Returns:
        A :class:`~energy_margin.report.render.View`.
    """
    positions = np.asarray(object_pos, dtype=float).reshape(-1, 3)
    radius = np.broadcast_to(np.asarray(object_radius, dtype=float), (positions.shape[0],))
    offsets = np.concatenate([np.eye(3), -np.eye(3)])
    points = [(positions[:, None, :] + radius[:, None, None] * offsets[None]).reshape(-1, 3), *region_bounds]
    azimuth, elevation = DEFAULT_AZIMUTH, DEFAULT_ELEVATION
    if camera is not None:
        azimuth, elevation = float(camera[0]), float(camera[1])
    view = fit_view(np.concatenate(points), elevation=elevation, azimuth=azimuth)
    if camera is not None and len(camera) == 3:
        view = View(view.lookat, float(camera[2]), azimuth, elevation)
    return view


def parse_camera(text: str) -> tuple[float, ...]:
    """``--camera AZIMUTH,ELEVATION[,DISTANCE]`` as numbers (degrees, degrees, m).

    Raises:
        InvalidParameterError: not two or three finite numbers, an elevation outside [-90, 90] or a distance <= 0.
    """
    try:
        values = tuple(float(part) for part in text.split(","))
    except ValueError:
        values = ()
    if len(values) not in (2, 3) or not all(np.isfinite(values)):
        raise InvalidParameterError("camera", f"takes AZIMUTH,ELEVATION[,DISTANCE] (degrees, degrees, m), got {text!r}")
    if not -90.0 <= values[1] <= 90.0:
        raise InvalidParameterError("camera", f"elevation {values[1]:g} is outside [-90, 90] degrees")
    if len(values) == 3 and values[2] <= 0.0:
        raise InvalidParameterError("camera", f"distance {values[2]:g} m must be > 0")
    return values


def render_scene(
    task: SceneTask,
    path: Path,
    *,
    seed: int = 0,
    width: int = 960,
    height: int = 720,
    camera: tuple[float, ...] | None = None,
) -> FrameState:
    """Write a PNG of the scene at t = 0 with its capture (blue) and success (green) sets; return the frame.

    ``camera``: see :func:`framed_view` (``None``: frame the objects and the regions from the
    default heading and pitch).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    loaded = task.loaded
    frame = start_frame(task, seed)
    # A compiled model (.mjb) cannot be edited: its regions go into a model of their own, drawn over it.
    binary = is_binary_model(loaded.spec.mjcf)
    model_spec = mujoco.MjSpec() if binary else compile_spec(loaded.spec, loaded.design_values)[0]
    extent = float(np.max(np.abs(frame.object_pos[:, :2]))) + 1.0
    region_bounds: list[np.ndarray] = []
    _add_region_geoms(model_spec, loaded.spec.capture, task.frame_lookup(frame), _CAPTURE_RGBA, extent, region_bounds)
    _add_region_geoms(model_spec, loaded.spec.success, task.frame_lookup(None), _SUCCESS_RGBA, extent, region_bounds)
    centre = frame.object_pos.mean(axis=0)
    model_spec.worldbody.add_light(pos=[centre[0], centre[1], centre[2] + 3.0], dir=[0.0, 0.0, -1.0], castshadow=False)
    overlay: tuple[mujoco.MjModel, mujoco.MjData] | None = None
    if binary:
        regions = model_spec.compile()
        overlay = (regions, mujoco.MjData(regions))
        mujoco.mj_forward(*overlay)
        model = copy.copy(loaded.model)
    else:
        model = model_spec.compile()
    model.vis.headlight.ambient[:] = 0.35
    model.vis.headlight.diffuse[:] = 0.5
    model.vis.global_.offwidth = max(int(model.vis.global_.offwidth), width)
    model.vis.global_.offheight = max(int(model.vis.global_.offheight), height)
    simulator = task.make_simulator(loaded.n_objects, task.default_friction(), np.ones(2))
    simulator.reset(frame)
    data = mujoco.MjData(model)
    posed = require(simulator, CompiledModel, purpose="the scene view").data
    data.qpos[:] = posed.qpos
    data.mocap_pos[:] = posed.mocap_pos
    data.mocap_quat[:] = posed.mocap_quat
    mujoco.mj_forward(model, data)
    view = framed_view(frame.object_pos, np.asarray(loaded.object_radius), region_bounds, camera=camera)
    free_camera = mujoco.MjvCamera()
    free_camera.lookat[:] = view.lookat
    free_camera.distance = view.distance
    free_camera.azimuth = view.azimuth
    free_camera.elevation = view.elevation
    image = _render(model, data, free_camera, width, height, overlay)
    figure, ax = plt.subplots(figsize=(width / 100, height / 100 + 0.4), dpi=100)
    ax.imshow(image)
    ax.set_axis_off()
    ax.set_title(f"{loaded.spec.path.name} at t = 0 (seed {seed}): capture set blue, success set green", fontsize=10)
    figure.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    staging = staging_directory(path.parent, path.name)
    try:
        figure.savefig(staging / path.name)
        (staging / path.name).replace(path)
    finally:
        plt.close(figure)
        for leftover in staging.iterdir():
            leftover.unlink()
        staging.rmdir()
    return frame
