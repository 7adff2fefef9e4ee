"""Figures of the report, drawn with matplotlib (imported lazily; the ``plot`` extra).

Scenes are drawn from the MuJoCo model of a frame, so any task is drawn the same way: every geom
is projected onto the view plane (``"top"``: x-y, ``"side"``: x-z) and filled by role (objects,
end-effector, obstacles). Regions are drawn by evaluating their ``contains`` on a grid.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from energy_margin.data.dataset import Dataset
    from energy_margin.planning import CostField

__all__ = [
    "cost_field_figure",
    "draw_cost_field",
    "draw_ellipse",
    "draw_region",
    "draw_scene",
    "frame_figure",
    "precision_recall_figure",
    "runtime_figure",
    "trajectory_scores_figure",
]

_VIEWS = {"top": (0, 1), "side": (0, 2)}
_COLOURS = {"object": "#f08c28", "robot": "#33a852", "static": "#8c8c8c"}


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _turn(origin: np.ndarray, first: np.ndarray, second: np.ndarray) -> float:
    """Z component of (first - origin) x (second - origin): > 0 for a left turn."""
    a, b = first - origin, second - origin
    return float(a[0] * b[1] - a[1] * b[0])


def _hull(points: np.ndarray) -> np.ndarray:
    """Convex hull of 2-D points (monotone chain), counter-clockwise, shape (h, 2)."""
    unique = np.unique(np.round(points, 12), axis=0)
    if len(unique) <= 2:
        return unique
    order = unique[np.lexsort((unique[:, 1], unique[:, 0]))]

    def half(sequence: np.ndarray) -> list[np.ndarray]:
        chain: list[np.ndarray] = []
        for point in sequence:
            while len(chain) >= 2 and _turn(chain[-2], chain[-1], point) <= 0:
                chain.pop()
            chain.append(point)
        return chain

    lower, upper = half(order), half(order[::-1])
    return np.array(lower[:-1] + upper[:-1])


def _geom_outline(
    kind: int, size: np.ndarray, position: np.ndarray, rotation: np.ndarray, axes: tuple[int, int]
) -> np.ndarray | None:
    import mujoco

    if kind == mujoco.mjtGeom.mjGEOM_BOX:
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float)
        corners = position + (signs * size[:3]) @ rotation.T
    elif kind == mujoco.mjtGeom.mjGEOM_CYLINDER:
        angles = np.linspace(0.0, 2.0 * np.pi, 32, endpoint=False)
        ring = np.column_stack([size[0] * np.cos(angles), size[0] * np.sin(angles), np.zeros_like(angles)])
        lid = np.array([0.0, 0.0, size[1]])
        local = np.vstack([ring + lid, ring - lid])
        corners = position + local @ rotation.T
    elif kind == mujoco.mjtGeom.mjGEOM_SPHERE:
        angles = np.linspace(0.0, 2.0 * np.pi, 32, endpoint=False)
        circle = np.zeros((32, 3))
        circle[:, axes[0]] = size[0] * np.cos(angles)
        circle[:, axes[1]] = size[0] * np.sin(angles)
        corners = position + circle
    else:
        return None
    return _hull(corners[:, list(axes)])


def draw_scene(ax: Any, simulator: Any, *, view: str = "top") -> None:
    """Draw every geom of a MuJoCo simulator's current state projected onto ``view``."""
    import mujoco
    from matplotlib.patches import Polygon

    model, data = simulator.model, simulator.data
    axes = _VIEWS[view]
    objects = set(int(b) for b in simulator.index.object_bodies)
    for geom in range(model.ngeom):
        body = int(model.geom_bodyid[geom])
        role = "object" if body in objects else ("static" if body == 0 else "robot")
        kind = int(model.geom_type[geom])
        if kind == mujoco.mjtGeom.mjGEOM_PLANE:
            if view == "side":
                ax.axhline(float(data.geom_xpos[geom][2]), color=_COLOURS["static"], lw=1.5)
            continue
        outline = _geom_outline(
            kind, model.geom_size[geom], data.geom_xpos[geom], data.geom_xmat[geom].reshape(3, 3), axes
        )
        if outline is None or len(outline) < 3:
            continue
        ax.add_patch(
            Polygon(outline, closed=True, facecolor=_COLOURS[role], edgecolor="black", lw=0.5, alpha=0.85, zorder=3)
        )


def draw_region(
    ax: Any, region: Any, extent: tuple[float, float, float, float], *, view: str, fixed: float, colour: str, label: str
) -> None:
    """Shade where ``region.contains`` holds on a grid over ``extent`` (the third coordinate = ``fixed``)."""
    axes = _VIEWS[view]
    first = np.linspace(extent[0], extent[1], 240)
    second = np.linspace(extent[2], extent[3], 240)
    grid_a, grid_b = np.meshgrid(first, second)
    points = np.full((*grid_a.shape, 3), fixed)
    points[..., axes[0]] = grid_a
    points[..., axes[1]] = grid_b
    inside = np.asarray(region.contains(points), dtype=float)
    if inside.any():
        ax.contourf(grid_a, grid_b, inside, levels=[0.5, 1.5], colors=[colour], alpha=0.25, zorder=1)
        ax.contour(grid_a, grid_b, inside, levels=[0.5], colors=[colour], linewidths=1.0, zorder=2)
    ax.plot([], [], color=colour, lw=6, alpha=0.4, label=label)


def draw_ellipse(ax: Any, points: np.ndarray, *, min_thickness: float) -> None:
    """Outline the minimum-volume ellipse of 2-D ``points`` (n, 2)."""
    from energy_margin.world.ellipsoid import min_volume_ellipsoid

    ellipse = min_volume_ellipsoid(points, min_thickness=min_thickness)
    angles = np.linspace(0.0, 2.0 * np.pi, 100)
    unit = np.column_stack([np.cos(angles), np.sin(angles)]) * ellipse.radii
    outline = ellipse.center + unit @ ellipse.rotation.T
    ax.plot(outline[:, 0], outline[:, 1], color="#6a3d9a", lw=1.2, ls="--", label="ellipse of object centres", zorder=4)


def _frame_extent(dataset: Dataset, trajectory: int, view: str, margin: float) -> tuple[float, float, float, float]:
    axes = _VIEWS[view]
    points = dataset.arrays["object_pos"][trajectory][..., list(axes)].reshape(-1, 2)
    low, high = points.min(axis=0) - margin, points.max(axis=0) + margin
    return float(low[0]), float(high[0]), float(low[1]), float(high[1])


def frame_figure(
    dataset: Dataset, trajectory: int, frames: list[int], path: Path, *, field: CostField | None = None
) -> None:
    """Draw frames of one trajectory (top view for planar tasks, side view otherwise) to ``path``."""
    from energy_margin.tasks import get_recorded_task

    plt = _pyplot()
    task = get_recorded_task(dataset.metadata["task"], dataset.metadata.get("task_config"))
    planar = task.planar
    view = "top" if planar else "side"
    arrays = dataset.arrays
    friction = float(arrays["friction"][trajectory])
    simulator = task.make_simulator(dataset.n_objects, friction, arrays["drive"][trajectory])
    scene = simulator.scene
    size = max(max(obj.geom.size) for obj in scene.objects)
    margin = 0.6 if planar else 12 * size
    extent = _frame_extent(dataset, trajectory, view, margin)
    figure, axes_list = plt.subplots(1, len(frames), figsize=(4.2 * len(frames), 4.2), squeeze=False)
    for ax, frame_index in zip(axes_list[0], frames, strict=True):
        frame = dataset.frame(trajectory, frame_index)
        simulator.reset(frame)
        fixed = float(np.mean(frame.object_pos[:, 2])) if planar else float(np.mean(frame.object_pos[:, 1]))
        draw_region(
            ax, task.capture_region(frame), extent, view=view, fixed=fixed, colour="#1f78b4", label="capture region"
        )
        draw_region(
            ax, task.success_region_at(frame), extent, view=view, fixed=fixed, colour="#33a02c", label="success region"
        )
        draw_scene(ax, simulator, view=view)
        if planar and dataset.n_objects >= 1:
            draw_ellipse(ax, frame.object_pos[:, :2], min_thickness=size)
        if field is not None and frame_index == frames[-1]:
            draw_cost_field(ax, field, view=view)
        captured = bool(arrays["captured"][trajectory, frame_index])
        time = float(arrays["frame_time"][trajectory, frame_index])
        ax.set_title(
            f"trajectory {trajectory}, frame {frame_index} (t = {time:.2f} s)\ncaptured: {'yes' if captured else 'no'}",
            fontsize=9,
        )
        ax.set_xlim(extent[0], extent[1])
        ax.set_ylim(extent[2], extent[3])
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]" if planar else "z [m]")
    axes_list[0][0].legend(loc="lower left", fontsize=7)
    figure.tight_layout()
    figure.savefig(path, dpi=90)
    plt.close(figure)


def draw_cost_field(ax: Any, field: CostField, *, view: str) -> Any:
    """Scatter every object's position at every node, coloured by the node's cost."""
    axes = _VIEWS[view]
    positions = field.object_pos[..., list(axes)]
    costs = np.repeat(field.costs, field.object_pos.shape[1])
    return ax.scatter(positions[..., 0].ravel(), positions[..., 1].ravel(), c=costs, s=3, cmap="viridis", zorder=5)


def cost_field_figure(
    dataset: Dataset, trajectory: int, frame_index: int, field: CostField, likelihood: np.ndarray, path: Path
) -> None:
    """The energy-cost field of one frame and the histogram of its likelihoods."""
    from energy_margin.tasks import get_recorded_task

    plt = _pyplot()
    task = get_recorded_task(dataset.metadata["task"], dataset.metadata.get("task_config"))
    planar = task.planar
    view = "top" if planar else "side"
    arrays = dataset.arrays
    friction = float(arrays["friction"][trajectory])
    simulator = task.make_simulator(dataset.n_objects, friction, arrays["drive"][trajectory])
    frame = dataset.frame(trajectory, frame_index)
    simulator.reset(frame)
    figure, (left, right) = plt.subplots(1, 2, figsize=(10, 4.2))
    draw_scene(left, simulator, view=view)
    points = draw_cost_field(left, field, view=view)
    figure.colorbar(points, ax=left, label="energy cost c [J]")
    axes = _VIEWS[view]
    reached = field.object_pos[..., list(axes)].reshape(-1, 2)
    pad = 0.1 if planar else 0.02
    left.set_xlim(reached[:, 0].min() - pad, reached[:, 0].max() + pad)
    left.set_ylim(reached[:, 1].min() - pad, reached[:, 1].max() + pad)
    left.set_aspect("equal")
    left.set_title(
        f"reached object positions, {field.nodes} nodes (trajectory {trajectory}, frame {frame_index})", fontsize=9
    )
    right.hist(likelihood, bins=40, color="#1f78b4")
    right.set_yscale("log")
    right.set_xlabel("likelihood L(z_m)")
    right.set_ylabel("nodes")
    right.set_title("likelihood of the reached states", fontsize=9)
    figure.tight_layout()
    figure.savefig(path, dpi=90)
    plt.close(figure)


def trajectory_scores_figure(dataset: Dataset, capture: np.ndarray, success: np.ndarray, path: Path) -> None:
    """Capture and success scores along every trajectory, with the labels.

    Three panels per row with their own axis labels; one legend above the grid, off the data.
    """
    plt = _pyplot()
    count = dataset.n_trajectories
    columns = min(3, count)
    rows = int(np.ceil(count / columns))
    figure, axes = plt.subplots(rows, columns, figsize=(4.2 * columns, 2.6 * rows + 0.6), squeeze=False, sharey=True)
    frames = np.arange(dataset.n_frames)
    captured = dataset.arrays["captured"]
    succeeded = dataset.success_labels()
    handles: list[Any] = []
    for trajectory in range(rows * columns):
        ax = axes[trajectory // columns][trajectory % columns]
        if trajectory >= count:
            ax.axis("off")
            continue
        lines = [
            ax.plot(frames, capture[trajectory], color="#1f78b4", marker="o", ms=3, lw=1.2, label="capture score")[0],
            ax.plot(frames, success[trajectory], color="#33a02c", marker="s", ms=3, lw=1.2, label="success score")[0],
            ax.scatter(
                frames,
                captured[trajectory].astype(float) * 1.08 - 0.04,
                marker="|",
                color="black",
                s=40,
                label="captured label (1 = captured)",
            ),
        ]
        handles = handles or lines
        ax.set_ylim(-0.1, 1.1)
        ax.set_xticks(frames)
        outcome = "success" if succeeded[trajectory] else "failure"
        ax.set_title(
            f"trajectory {trajectory}: {outcome}", fontsize=9, color="#33a02c" if succeeded[trajectory] else "#e31a1c"
        )
        ax.tick_params(labelsize=8)
        ax.set_xlabel("frame", fontsize=8)
        if trajectory % columns == 0:
            ax.set_ylabel("score", fontsize=8)
    figure.legend(handles=handles, loc="upper center", ncol=3, fontsize=8, frameon=False)
    figure.tight_layout(rect=(0.0, 0.0, 1.0, 1.0 - 0.5 / (2.6 * rows + 0.6)))
    figure.savefig(path, dpi=80)
    plt.close(figure)


def precision_recall_figure(curves: dict[str, tuple[np.ndarray, np.ndarray]], path: Path, *, title: str) -> None:
    r"""Precision-recall curves, one per entry ``name -> (labels, scores)``, each with its chance line.

    The chance line of a curve is its positive rate: the precision of scores that know nothing.
    Names are matplotlib text (mathtext such as ``$\hat{k}$`` works).
    """
    from sklearn.metrics import average_precision_score, precision_recall_curve

    plt = _pyplot()
    figure, ax = plt.subplots(figsize=(5.0, 4.4))
    for name, (labels, scores) in curves.items():
        labels = np.asarray(labels, dtype=bool).ravel()
        if labels.all() or not labels.any():
            continue
        precision, recall, _ = precision_recall_curve(labels, np.asarray(scores).ravel())
        ap = average_precision_score(labels, np.asarray(scores).ravel())
        (line,) = ax.step(recall, precision, where="post", label=f"{name} (AP {ap:.3f})")
        rate = float(labels.mean())
        ax.axhline(rate, color=line.get_color(), ls=":", lw=1.0, label=f"chance, {name} ({rate:.2f})")
    ax.set_xlabel("recall")
    ax.set_ylabel("precision")
    ax.set_xlim(0, 1.02)
    ax.set_ylim(0, 1.05)
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=8.5, loc="upper left", bbox_to_anchor=(1.02, 1.0), frameon=False)
    figure.tight_layout()
    figure.savefig(path, dpi=100, bbox_inches="tight")
    plt.close(figure)


def runtime_figure(rows: list[dict[str, Any]], path: Path, *, paper: dict[int, dict[str, Any]] | None = None) -> None:
    """Runtime per frame (mean and standard deviation) against the number of objects, beside the paper's."""
    plt = _pyplot()
    figure, ax = plt.subplots(figsize=(5.6, 4.2))
    objects = [row["n_objects"] for row in rows]
    ax.errorbar(
        objects,
        [row["runtime_per_frame_s"] for row in rows],
        yerr=[row["runtime_per_frame_std_s"] for row in rows],
        marker="o",
        capsize=3,
        color="#1f78b4",
        label="this project (this machine)",
    )
    if paper:
        sizes = sorted(paper)
        ax.errorbar(
            sizes,
            [paper[n]["runtime"][0] for n in sizes],
            yerr=[paper[n]["runtime"][1] for n in sizes],
            marker="s",
            capsize=3,
            color="#e31a1c",
            ls="--",
            label="paper (Fig. 2, PyBullet)",
        )
    ax.set_xlabel("number of objects $n_o$")
    ax.set_ylabel("runtime per frame [s]")
    ax.set_title("Algorithm 1 runtime against the number of objects", fontsize=9)
    ax.set_ylim(bottom=0)
    ax.legend(fontsize=8, loc="upper left")
    figure.tight_layout()
    figure.savefig(path, dpi=90)
    plt.close(figure)
