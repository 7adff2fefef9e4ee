"""Rendered frames: the scene as MuJoCo draws it, with translucent regions and the tree's reached states.

:class:`FrameRenderer` draws a frame of a task with MuJoCo's own offscreen renderer (``mjr_render``)
on an OpenGL context chosen by ``MUJOCO_GL`` (when unset: ``egl``, headless, on Linux and
``glfw`` elsewhere; ``osmesa`` where set). The capture and success regions are drawn as translucent solids (from a
region's :meth:`~energy_margin.tasks.base.DrawableRegion.shapes`, or as a grid of cells where its
``contains`` holds for a region without shapes), and the object positions of every node of a
frame's tree as small spheres coloured by the node's likelihood (viridis, log scale).

When no OpenGL context can be made, one warning line is printed and the frame is drawn as
today's matplotlib projection (:mod:`energy_margin.report.plots`) of the same size instead.

This module draws the frames; the camera and colours are in :mod:`~energy_margin.report.render_view`
and the region solids and tree markers in :mod:`~energy_margin.report.render_markers`.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from energy_margin.errors import EnergyMarginError, InvalidParameterError, check_choice, check_int
from energy_margin.report.render_markers import (
    drawn_inside,
    region_shapes,
    shape_markers,
    tree_markers,
)
from energy_margin.report.render_view import (
    CAPTURE_RGBA,
    LIKELIHOOD_DECADES,
    SUCCESS_RGBA,
    View,
    fit_view,
    likelihood_scale,
    near_objects,
    scene_view,
    viridis,
)

if TYPE_CHECKING:
    from energy_margin.data.dataset import Dataset
    from energy_margin.planning import CostField
    from energy_margin.sim.mujoco_backend import MujocoSimulator
    from energy_margin.tasks.base import Region, Task
    from energy_margin.world.state import FrameState

__all__ = [
    "CAPTURE_RGBA",
    "LIKELIHOOD_DECADES",
    "SUCCESS_RGBA",
    "FrameRenderer",
    "View",
    "check_trajectory",
    "dataset_renderer",
    "drawn_inside",
    "fit_view",
    "likelihood_scale",
    "near_objects",
    "region_shapes",
    "save_png",
    "scene_view",
    "shape_markers",
    "tree_markers",
    "viridis",
    "warn_once",
]


_warned: set[str] = set()


def warn_once(message: str) -> None:
    """Print ``energy-margin: warning: message`` on standard error, once per process."""
    if message not in _warned:
        _warned.add(message)
        print(f"energy-margin: warning: {message}", file=sys.stderr, flush=True)


def _gl_context_class() -> Any:
    """The GL context class ``MUJOCO_GL`` names (unset: EGL, headless, on Linux; GLFW elsewhere)."""
    backend = os.environ.get("MUJOCO_GL", "").strip().lower() or ("egl" if sys.platform.startswith("linux") else "glfw")
    if backend == "egl":
        from mujoco.egl import GLContext
    elif backend == "osmesa":
        from mujoco.osmesa import GLContext
    elif backend == "glfw":
        from mujoco.glfw import GLContext
    else:
        raise RuntimeError(f"MUJOCO_GL={backend!r} names no GL backend this renderer knows (egl, osmesa, glfw)")
    return GLContext


class _MujocoCanvas:
    """An offscreen MuJoCo render context for one model: scene, camera and pixel read-back."""

    def __init__(self, model: Any, width: int, height: int, max_geom: int) -> None:
        import mujoco

        self.model = model
        self.width, self.height = width, height
        model.vis.global_.offwidth = max(int(model.vis.global_.offwidth), width)
        model.vis.global_.offheight = max(int(model.vis.global_.offheight), height)
        # Built-in meshes with 16 slices and 8 stacks (MuJoCo's default 28 and 16): a tree's
        # thousands of spheres draw 2.4 times faster in software (llvmpipe), and a picture at
        # 640 x 480 looks the same (docs/howto/report.md).
        model.vis.quality.numslices = 16
        model.vis.quality.numstacks = 8
        # A brighter headlight than MuJoCo's default: the generated models have no lights.
        model.vis.headlight.ambient[:] = 0.45
        model.vis.headlight.diffuse[:] = 0.6
        model.vis.headlight.specular[:] = 0.2
        self._gl = _gl_context_class()(width, height)
        self._gl.make_current()
        self._context = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_150)
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._context)
        self.scene = mujoco.MjvScene(model, maxgeom=max_geom)
        self._option = mujoco.MjvOption()
        self._camera = mujoco.MjvCamera()
        self._viewport = mujoco.MjrRect(0, 0, width, height)

    def draw(
        self, data: Any, view: View, markers: list[tuple[int, np.ndarray, np.ndarray, np.ndarray, np.ndarray]]
    ) -> np.ndarray:
        import mujoco

        camera = self._camera
        camera.type = mujoco.mjtCamera.mjCAMERA_FREE
        camera.lookat[:] = view.lookat
        camera.distance = view.distance
        camera.azimuth = view.azimuth
        camera.elevation = view.elevation
        self._gl.make_current()
        mujoco.mjv_updateScene(self.model, data, self._option, None, camera, mujoco.mjtCatBit.mjCAT_ALL, self.scene)
        scene = self.scene
        room = scene.maxgeom - scene.ngeom
        if len(markers) > room:
            warn_once(f"only {room} of {len(markers)} markers fit in the render scene; the rest are left out")
        for kind, size, position, rotation, rgba in markers[:room]:
            mujoco.mjv_initGeom(scene.geoms[scene.ngeom], kind, size, position, rotation.ravel(), rgba)
            scene.ngeom += 1
        mujoco.mjr_render(self._viewport, scene, self._context)
        pixels = np.empty((self.height, self.width, 3), dtype=np.uint8)
        mujoco.mjr_readPixels(pixels, None, self._viewport, self._context)
        return np.flipud(pixels).copy()

    def project(self, points: np.ndarray) -> np.ndarray:
        """Pixel coordinates (n, 2) (column, row from the top-left) of points (n, 3) in the last drawn view."""
        # The scene holds the two eyes of a stereo pair (ipd apart); a mono picture is drawn from
        # their midpoint.
        left, right_eye = self.scene.camera[0], self.scene.camera[1]
        camera = left
        position = 0.5 * (np.asarray(left.pos, dtype=float) + np.asarray(right_eye.pos, dtype=float))
        forward = np.asarray(camera.forward, dtype=float)
        up = np.asarray(camera.up, dtype=float)
        right = np.cross(forward, up)
        relative = np.asarray(points, dtype=float).reshape(-1, 3) - position
        depth = relative @ forward
        # The perspective frustum of mjr_render: focal length in pixels from its near plane.
        focal = 0.5 * self.height * float(camera.frustum_near) / float(camera.frustum_top)
        column = 0.5 * self.width + focal * (relative @ right) / depth
        row = 0.5 * self.height - focal * (relative @ up) / depth
        return np.column_stack([column, row])

    def close(self) -> None:
        self._gl.make_current()
        self._context.free()
        self._gl.free()


class FrameRenderer:
    """Draws frames of one scene; MuJoCo's renderer where a GL context can be made, matplotlib otherwise.

    Args:
        simulator: a MuJoCo simulator of the scene (its model and data are drawn).
        task: the task (its regions).
        width: image width, pixels.
        height: image height, pixels.
        max_geom: most geoms one picture may hold (scene, regions, tree markers).
        backend: ``"auto"`` (MuJoCo, else the fallback with a warning), ``"mujoco"`` (raise
            :class:`EnergyMarginError` without GL) or ``"matplotlib"``.

    """

    def __init__(
        self,
        simulator: MujocoSimulator,
        task: Task,
        *,
        width: int = 640,
        height: int = 480,
        max_geom: int = 20000,
        backend: str = "auto",
    ) -> None:
        check_choice("backend", backend, ("auto", "mujoco", "matplotlib"))
        check_int("width", width, minimum=16, maximum=4096)
        check_int("height", height, minimum=16, maximum=4096)
        self.simulator = simulator
        self.task = task
        self.width, self.height = width, height
        self._canvas: _MujocoCanvas | None = None
        if backend != "matplotlib":
            try:
                self._canvas = _MujocoCanvas(simulator.model, width, height, max_geom)
            except Exception as error:  # every GL failure (no library, no device, no display) looks different
                reason = " ".join(f"{type(error).__name__}: {error}".split())
                if backend == "mujoco":
                    raise EnergyMarginError(f"no OpenGL context for MuJoCo's renderer ({reason})") from None
                warn_once(
                    f"no OpenGL context for MuJoCo's renderer ({reason[:160]}); drawing matplotlib projections "
                    "instead (docs/howto/report.md says what to install)"
                )
        self.backend = "mujoco" if self._canvas is not None else "matplotlib"

    def __enter__(self) -> FrameRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Free the GL context."""
        if self._canvas is not None:
            self._canvas.close()
            self._canvas = None

    def view_points(self, frame: FrameState, field: CostField | None = None) -> np.ndarray:
        """Points a view of ``frame`` must hold: objects, end-effector geoms, tree positions; (n, 3), m."""
        self.simulator.reset(frame)
        model, data = self.simulator.model, self.simulator.data
        robot = [g for g in range(model.ngeom) if model.geom_bodyid[g] != 0]
        objects = np.asarray(frame.object_pos, dtype=float)
        parts = [objects, near_objects(data.geom_xpos[robot], objects)]
        if field is not None:
            parts.append(field.object_pos.reshape(-1, 3))
        return np.concatenate(parts)

    def render(
        self,
        frame: FrameState,
        *,
        view: View | None = None,
        field: CostField | None = None,
        likelihoods: np.ndarray | None = None,
        regions: bool = True,
    ) -> np.ndarray:
        """The picture of ``frame``, shape (height, width, 3), uint8 RGB.

        Args:
            frame: the state drawn.
            view: the camera (``None``: :func:`scene_view` of the frame and its tree).
            field: the frame's energy-cost field; its nodes' object positions are drawn.
            likelihoods: likelihood of every node of ``field``, shape (M,); required with ``field``.
            regions: draw the capture region (built from ``frame``) and the success region.

        """
        if field is not None and (likelihoods is None or np.shape(likelihoods) != (field.nodes,)):
            raise InvalidParameterError("likelihoods", f"must have shape ({field.nodes},) with a field")
        if view is None:
            view = scene_view(self.simulator.scene, self.view_points(frame, field))
        self.simulator.reset(frame)
        region_list = self._regions(frame) if regions else []
        if self._canvas is None:
            return self._render_projection(frame, view, field, likelihoods, region_list)
        markers: list[tuple[Any, ...]] = []
        extent = self._extent(view)
        height = float(np.mean(frame.object_pos[:, 2]))
        for region, rgba in region_list:
            for shape in region_shapes(region, extent, height=height):
                markers.extend(shape_markers(shape, rgba))
        if field is not None and likelihoods is not None:
            size = min(min(obj.geom.size) for obj in self.simulator.scene.objects)
            markers.extend(tree_markers(field, likelihoods, radius=0.35 * size))
        return self._canvas.draw(self.simulator.data, view, markers)

    def project(self, points: np.ndarray) -> np.ndarray:
        """Pixel coordinates (n, 2) (column, row) of world points (n, 3), m, in the last MuJoCo picture."""
        if self._canvas is None:
            raise EnergyMarginError("projection needs MuJoCo's renderer (no OpenGL context)")
        return self._canvas.project(points)

    def _regions(self, frame: FrameState) -> list[tuple[Region, tuple[float, float, float, float]]]:
        return [(self.task.capture_region(frame), CAPTURE_RGBA), (self.task.success_region_at(frame), SUCCESS_RGBA)]

    @staticmethod
    def _extent(view: View) -> np.ndarray:
        centre = np.asarray(view.lookat)
        reach = view.distance
        return np.array([centre - reach, centre + reach])

    def _render_projection(
        self,
        frame: FrameState,
        view: View,
        field: CostField | None,
        likelihoods: np.ndarray | None,
        regions: list[tuple[Region, tuple[float, float, float, float]]],
    ) -> np.ndarray:
        """The matplotlib fallback: top view for planar tasks, side view otherwise."""
        from energy_margin.report import plots

        plt = plots._pyplot()
        planar = view.elevation <= -45.0
        projection = "top" if planar else "side"
        axes = plots._VIEWS[projection]
        half = view.distance * np.tan(np.radians(22.5)) * 1.1
        centre = np.asarray(view.lookat)
        extent = (
            float(centre[axes[0]] - half * self.width / self.height),
            float(centre[axes[0]] + half * self.width / self.height),
            float(centre[axes[1]] - half),
            float(centre[axes[1]] + half),
        )
        figure = plt.figure(figsize=(self.width / 100.0, self.height / 100.0), dpi=100)
        ax = figure.add_axes((0.0, 0.0, 1.0, 1.0))
        fixed = float(np.mean(frame.object_pos[:, 2 if planar else 1]))
        for region, rgba in regions:
            colour = "#" + "".join(f"{int(255 * c):02x}" for c in rgba[:3])
            plots.draw_region(ax, region, extent, view=projection, fixed=fixed, colour=colour, label="")
        plots.draw_scene(ax, self.simulator, view=projection)
        if field is not None and likelihoods is not None:
            positions = field.object_pos[..., list(axes)].reshape(-1, 2)
            colours = np.repeat(viridis(likelihood_scale(likelihoods)), field.object_pos.shape[1], axis=0)
            ax.scatter(positions[:, 0], positions[:, 1], c=colours, s=4, zorder=5)
        ax.set_xlim(extent[0], extent[1])
        ax.set_ylim(extent[2], extent[3])
        ax.set_axis_off()
        figure.canvas.draw()
        pixels = np.asarray(figure.canvas.buffer_rgba())[..., :3].copy()
        plt.close(figure)
        return pixels


def dataset_renderer(dataset: Dataset, trajectory: int, **options: Any) -> FrameRenderer:
    """A :class:`FrameRenderer` of one trajectory's scene (its friction and drive), drawn by MuJoCo."""
    from energy_margin.sim.mujoco_backend import MujocoSimulator

    check_trajectory(dataset, trajectory)
    arrays = dataset.arrays
    task = dataset.task
    simulator = task.make_simulator(
        dataset.n_objects, float(arrays["friction"][trajectory]), arrays["drive"][trajectory]
    )
    assert isinstance(simulator, MujocoSimulator)
    return FrameRenderer(simulator, task, **options)


def check_trajectory(dataset: Dataset, trajectory: int, frame: int | None = None) -> None:
    """Raise :class:`EnergyMarginError` when the trajectory (or frame) index is not in the dataset."""
    where = dataset.path if dataset.path is not None else "the dataset"
    if not 0 <= trajectory < dataset.n_trajectories:
        raise EnergyMarginError(
            f"{where} has no trajectory {trajectory} (trajectories 0 to {dataset.n_trajectories - 1})"
        )
    if frame is not None and not 0 <= frame < dataset.n_frames:
        raise EnergyMarginError(f"{where} has no frame {frame} (frames 0 to {dataset.n_frames - 1})")


def save_png(pixels: np.ndarray, path: Path | str) -> None:
    """Write an image (H, W, 3) uint8 as PNG, atomically (matplotlib's writer)."""
    import matplotlib.image

    from energy_margin.runs.files import atomic_path

    with atomic_path(Path(path)) as temporary:
        matplotlib.image.imsave(temporary, pixels, format="png")
