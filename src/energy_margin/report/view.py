"""The interactive 3-D view of one frame's energy-cost field: one self-contained HTML file (plotly).

The page holds the scene's bodies as drawn by the frame's MuJoCo model, the capture and success
regions as translucent solids, every tree node's object positions coloured by the node's likelihood
(log10, viridis; hover for node, parent, cost and likelihood) and, on demand (legend entry or the
button), the edges from every node's object positions to its parent's. plotly.js is embedded in
the page, so it opens in any browser with no server and no network.
"""

from __future__ import annotations

import html
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from energy_margin.errors import EnergyMarginError, InvalidParameterError

if TYPE_CHECKING:
    from energy_margin.report.frame_tree import AnalysedTree
    from energy_margin.tasks.base import RegionShape

__all__ = [
    "region_meshes",
    "scene_meshes",
    "solid_mesh",
    "view_figure",
    "write_view",
]

_CYLINDER_SIDES = 24
_ROLE_COLOURS = {"object": "rgb(240,140,40)", "robot": "rgb(51,168,82)", "static": "rgb(170,170,170)"}


def _plotly() -> Any:
    try:
        import plotly.graph_objects as go
    except ImportError:
        raise EnergyMarginError("the interactive view needs plotly: pip install 'energy-margin[render]'") from None
    return go


def solid_mesh(
    kind: str, half_size: np.ndarray, centre: np.ndarray, rotation: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (n, 3), m, and triangles (k, 3) of a box (half extents) or a z-axis cylinder (radius, half height).

    Args:
        kind: ``"box"``, ``"cylinder"`` or ``"sphere"`` (radius).
        half_size: shape (3,), m.
        centre: shape (3,), m.
        rotation: world-from-solid rotation matrix, shape (3, 3).

    """
    half_size = np.asarray(half_size, dtype=float)
    if kind == "box":
        signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
        local = signs * half_size[:3]
        faces = np.array(
            [
                [0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3],
            ]
        )  # fmt: skip
    elif kind in ("cylinder", "sphere"):
        angles = np.linspace(0.0, 2.0 * np.pi, _CYLINDER_SIDES, endpoint=False)
        radius = half_size[0]
        if kind == "cylinder":
            rings = [(-half_size[1], radius), (half_size[1], radius)]
        else:
            rings = [(radius * np.cos(t), radius * np.sin(t)) for t in np.linspace(np.pi, 0.0, 9)[1:-1]]
        local_rings = [
            np.column_stack([r * np.cos(angles), r * np.sin(angles), np.full_like(angles, z)]) for z, r in rings
        ]
        local = np.vstack([*local_rings, [[0.0, 0.0, rings[0][0] if kind == "cylinder" else -radius]]])
        local = np.vstack([local, [[0.0, 0.0, rings[-1][0] if kind == "cylinder" else radius]]])
        n = _CYLINDER_SIDES
        bottom, top = len(local) - 2, len(local) - 1
        triangles = []
        for ring in range(len(local_rings) - 1):
            for i in range(n):
                a, b = ring * n + i, ring * n + (i + 1) % n
                triangles += [[a, b, b + n], [a, b + n, a + n]]
        last = (len(local_rings) - 1) * n
        for i in range(n):
            triangles += [[bottom, (i + 1) % n, i], [top, last + i, last + (i + 1) % n]]
        faces = np.array(triangles)
    else:
        raise InvalidParameterError("kind", f"must be 'box', 'cylinder' or 'sphere', got {kind!r}")
    vertices = np.asarray(centre, dtype=float) + local @ np.asarray(rotation, dtype=float).T
    return vertices, faces


def _clip_box(centre: np.ndarray, half: np.ndarray, bounds: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """An axis-aligned box cut to ``bounds`` (2, 3), or ``None`` when nothing is left."""
    low = np.maximum(centre - half, bounds[0])
    high = np.minimum(centre + half, bounds[1])
    if np.any(high <= low):
        return None
    return 0.5 * (low + high), 0.5 * (high - low)


def _merge(meshes: list[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    vertices, faces, offset = [], [], 0
    for v, f in meshes:
        vertices.append(v)
        faces.append(f + offset)
        offset += len(v)
    return np.vstack(vertices), np.vstack(faces)


def _mesh_trace(go: Any, meshes: list[tuple[np.ndarray, np.ndarray]], *, name: str, colour: str, opacity: float) -> Any:
    vertices, faces = _merge(meshes)
    return go.Mesh3d(
        x=vertices[:, 0],
        y=vertices[:, 1],
        z=vertices[:, 2],
        i=faces[:, 0],
        j=faces[:, 1],
        k=faces[:, 2],
        color=colour,
        opacity=opacity,
        flatshading=True,
        name=name,
        showlegend=True,
        hoverinfo="name",
    )


def scene_meshes(simulator: Any, bounds: np.ndarray) -> dict[str, list[tuple[np.ndarray, np.ndarray]]]:
    """Meshes of every geom of a MuJoCo simulator's current state by role (object, robot, static).

    Axis-aligned static boxes and ground planes are cut to ``bounds`` (2, 3), m, so a long wall or
    a large floor does not dwarf the objects.
    """
    import mujoco

    model, data = simulator.model, simulator.data
    objects = {int(b) for b in simulator.index.object_bodies}
    meshes: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {"object": [], "robot": [], "static": []}
    for geom in range(model.ngeom):
        body = int(model.geom_bodyid[geom])
        role = "object" if body in objects else ("static" if body == 0 else "robot")
        kind = int(model.geom_type[geom])
        size = np.asarray(model.geom_size[geom], dtype=float)
        centre = np.asarray(data.geom_xpos[geom], dtype=float)
        rotation = np.asarray(data.geom_xmat[geom], dtype=float).reshape(3, 3)
        aligned = np.allclose(rotation, np.eye(3))
        if kind == mujoco.mjtGeom.mjGEOM_PLANE:
            if not aligned:
                continue
            kind, size = mujoco.mjtGeom.mjGEOM_BOX, np.array([size[0], size[1], 0.0005])
            centre = centre - np.array([0.0, 0.0, 0.0005])
        if kind == mujoco.mjtGeom.mjGEOM_BOX:
            if role == "static" and aligned:
                clipped = _clip_box(centre, size, bounds)
                if clipped is None:
                    continue
                centre, size = clipped
            meshes[role].append(solid_mesh("box", size, centre, rotation))
        elif kind == mujoco.mjtGeom.mjGEOM_CYLINDER:
            meshes[role].append(solid_mesh("cylinder", size, centre, rotation))
        elif kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
            meshes[role].append(solid_mesh("cylinder", np.array([size[0], size[1] + size[0], 0.0]), centre, rotation))
        elif kind == mujoco.mjtGeom.mjGEOM_SPHERE:
            meshes[role].append(solid_mesh("sphere", size, centre, rotation))
    return meshes


def region_meshes(shapes: tuple[RegionShape, ...], bounds: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Meshes of a region's solids; unrotated boxes that reach into ``bounds`` (2, 3), m, are cut to it."""
    meshes = []
    for shape in shapes:
        centre, half = np.asarray(shape.centre, dtype=float), np.asarray(shape.half_size, dtype=float)
        cos, sin = np.cos(shape.yaw), np.sin(shape.yaw)
        rotation = np.array([[cos, -sin, 0.0], [sin, cos, 0.0], [0.0, 0.0, 1.0]])
        if shape.kind == "box" and shape.yaw == 0.0:
            # A region away from the frame's bodies is still drawn, uncut.
            clipped = _clip_box(centre, half, bounds)
            if clipped is not None:
                centre, half = clipped
        meshes.append(solid_mesh(shape.kind, half, centre, rotation))
    return meshes


def view_figure(tree: AnalysedTree) -> Any:
    """The plotly figure of an analysed frame's tree (see the module docstring)."""
    from energy_margin.report.render import near_objects
    from energy_margin.sim.mujoco_backend import MujocoSimulator

    go = _plotly()
    dataset, field, frame = tree.dataset, tree.field, tree.frame
    arrays = dataset.arrays
    task = dataset.task
    simulator = task.make_simulator(
        dataset.n_objects, float(arrays["friction"][tree.trajectory]), arrays["drive"][tree.trajectory]
    )
    assert isinstance(simulator, MujocoSimulator)
    scene = simulator.scene
    simulator.reset(frame)
    model, data = simulator.model, simulator.data
    robot = [g for g in range(model.ngeom) if model.geom_bodyid[g] != 0]
    points = np.concatenate([field.object_pos.reshape(-1, 3), near_objects(data.geom_xpos[robot], frame.object_pos)])
    low, high = points.min(axis=0), points.max(axis=0)
    margin = 0.25 * float(np.max(high - low)) + max(max(obj.geom.size) for obj in scene.objects)
    bounds = np.array([low - margin, high + margin])

    traces = _scene_traces(go, simulator, tree, bounds)
    traces.append(_node_trace(go, tree))
    traces.append(_edge_trace(go, tree))
    figure = go.Figure(data=traces)
    _lay_out(figure, tree, planar=scene.object_motion == "upright", edge_trace=len(traces) - 1)
    return figure


def _scene_traces(go: Any, simulator: Any, tree: AnalysedTree, bounds: np.ndarray) -> list[Any]:
    """Meshes of the objects, end-effector and statics, then the capture and success regions, within ``bounds`` (m)."""
    from energy_margin.report.render import CAPTURE_RGBA, SUCCESS_RGBA, region_shapes

    task, frame = tree.dataset.task, tree.frame
    traces = []
    names = {"object": "objects (frame)", "robot": "end-effector", "static": "statics"}
    for role, meshes in scene_meshes(simulator, bounds).items():
        if meshes:
            traces.append(_mesh_trace(go, meshes, name=names[role], colour=_ROLE_COLOURS[role], opacity=1.0))
    height = float(np.mean(frame.object_pos[:, 2]))
    for label, region, rgba in (
        ("capture region", task.capture_region(frame), CAPTURE_RGBA),
        ("success region", task.success_region_at(frame), SUCCESS_RGBA),
    ):
        meshes = region_meshes(region_shapes(region, bounds, height=height), bounds)
        if meshes:
            colour = "rgb({:.0f},{:.0f},{:.0f})".format(*(255 * c for c in rgba[:3]))
            traces.append(_mesh_trace(go, meshes, name=label, colour=colour, opacity=0.25))
    return traces


def _node_trace(go: Any, tree: AnalysedTree) -> Any:
    """Every node's object positions (m), coloured by log10 likelihood, with node, parent and cost (J)."""
    field = tree.field
    n_nodes, n_objects = field.object_pos.shape[:2]
    nodes = np.repeat(np.arange(n_nodes), n_objects)
    objects = np.tile(np.arange(n_objects), n_nodes)
    positions = field.object_pos.reshape(-1, 3)
    log_likelihood = np.log10(np.maximum(np.repeat(tree.likelihoods, n_objects), 1e-300))
    parents = np.repeat(field.parents, n_objects)
    costs = np.repeat(field.costs, n_objects)
    return go.Scatter3d(
        x=positions[:, 0],
        y=positions[:, 1],
        z=positions[:, 2],
        mode="markers",
        name=f"tree nodes ({n_nodes} × {n_objects} object positions)",
        marker={
            "size": 3,
            "color": log_likelihood,
            "colorscale": "Viridis",
            "cmin": float(log_likelihood.max()) - 6.0,
            "cmax": float(log_likelihood.max()),
            "colorbar": {"title": {"text": "log10 likelihood"}, "x": 1.0},
        },
        customdata=np.column_stack([nodes, objects, parents, costs, log_likelihood]),
        hovertemplate=(
            "node %{customdata[0]}, object %{customdata[1]}<br>parent %{customdata[2]}<br>"
            "cost %{customdata[3]:.3g} J<br>log10 L %{customdata[4]:.2f}<extra></extra>"
        ),
    )


def _edge_trace(go: Any, tree: AnalysedTree) -> Any:
    """The segments from every node's object positions to its parent's (hidden until shown)."""
    field = tree.field
    children = np.flatnonzero(field.parents >= 0)
    start = field.object_pos[field.parents[children]].reshape(-1, 3)
    end = field.object_pos[children].reshape(-1, 3)
    # Each edge is a segment and a gap (NaN) before the next.
    pairs = np.full((len(start), 3, 3), np.nan)
    pairs[:, 0], pairs[:, 1] = start, end
    segments = pairs.reshape(-1, 3)
    return go.Scatter3d(
        x=segments[:, 0],
        y=segments[:, 1],
        z=segments[:, 2],
        mode="lines",
        name="edges to parents",
        line={"color": "rgba(60,60,60,0.5)", "width": 2},
        hoverinfo="skip",
        visible="legendonly",
        connectgaps=False,
    )


def _lay_out(figure: Any, tree: AnalysedTree, *, planar: bool, edge_trace: int) -> None:
    """The title (frame, scores, nodes), the camera, the legend and the buttons of trace ``edge_trace``."""
    dataset = tree.dataset
    n_nodes = tree.field.object_pos.shape[0]
    time = float(dataset.arrays["frame_time"][tree.trajectory, tree.frame_index])
    title = (
        f"{html.escape(dataset.metadata['task'])}: trajectory {tree.trajectory}, frame {tree.frame_index} "
        f"(t = {time:.2f} s): capture {tree.stored['capture_score']:.3f}, success "
        f"{tree.stored['success_score']:.3f}; {n_nodes} nodes, λ = {tree.likelihood_lambda:g} 1/J"
    )
    # From the front (−y) and above: the pusher's wall or the gripper's far side is at the back.
    eye = {"x": 0.0, "y": -1.5, "z": 1.3} if planar else {"x": 1.0, "y": -1.5, "z": 0.6}
    figure.update_layout(
        title={"text": title, "font": {"size": 14}},
        scene={
            "aspectmode": "data",
            "camera": {"eye": eye},
            "xaxis": {"title": {"text": "x [m]"}},
            "yaxis": {"title": {"text": "y [m]"}},
            "zaxis": {"title": {"text": "z [m]"}},
        },
        legend={"x": 0.0, "y": 1.0, "bgcolor": "rgba(255,255,255,0.7)"},
        margin={"l": 0, "r": 0, "t": 40, "b": 0},
        updatemenus=[
            {
                "type": "buttons",
                "direction": "left",
                "x": 0.0,
                "y": 0.0,
                "xanchor": "left",
                "yanchor": "bottom",
                "buttons": [
                    {"label": "show edges", "method": "restyle", "args": [{"visible": True}, [edge_trace]]},
                    {"label": "hide edges", "method": "restyle", "args": [{"visible": "legendonly"}, [edge_trace]]},
                ],
            }
        ],
    )


def write_view(tree: AnalysedTree, path: Path | str) -> Path:
    """Write the self-contained HTML view of ``tree`` to ``path`` (atomically); return the path."""
    from energy_margin.runs.files import atomic_write_text

    path = Path(path)
    figure = view_figure(tree)
    page = figure.to_html(include_plotlyjs=True, full_html=True, config={"displaylogo": False})
    if not path.parent.is_dir():
        raise EnergyMarginError(f"cannot write {path}: {path.parent} is not a directory")
    atomic_write_text(path, page)
    return path
