"""What a scene file declares, in words and as a picture (``energy-margin scene``).

:func:`describe_scene` (:mod:`energy_margin.report.scene_text`) lists the objects with their
masses, the actuators and mocap bodies, the motion's duration, the sets and the wrench ranges.
:func:`render_scene` draws the scene at t = 0
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
from energy_margin.report.scene_text import describe_scene
from energy_margin.runs.files import staging_directory
from energy_margin.sim.base import CompiledModel, require
from energy_margin.tasks.model_file import is_binary_model
from energy_margin.tasks.scene_model import compile_spec
from energy_margin.tasks.scene_task import SceneTask
from energy_margin.world.state import FrameState

__all__ = ["describe_scene", "framed_view", "parse_camera", "render_scene", "start_frame"]

_CAPTURE_RGBA = (0.12, 0.47, 0.71, 0.3)
_SUCCESS_RGBA = (0.2, 0.63, 0.17, 0.3)
_EXCLUDED_RGBA = (0.9, 0.1, 0.1, 0.25)


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
