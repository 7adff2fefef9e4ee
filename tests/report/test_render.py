"""Rendered frames: MuJoCo's offscreen renderer, regions, tree points and the matplotlib fallback."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from energy_margin.analysis.frame import AnalyzerConfig, analyze_frame
from energy_margin.analysis.scores import likelihood
from energy_margin.data.dataset import Dataset, load_dataset
from energy_margin.data.generate import generate_dataset
from energy_margin.errors import EnergyMarginError
from energy_margin.report import render
from energy_margin.tasks import get_task
from energy_margin.tasks.base import DrawableRegion
from energy_margin.tasks.pushing import SweptRegion

pytest.importorskip("matplotlib")


@pytest.fixture(scope="module")
def scooping_dataset(tmp_path_factory: pytest.TempPathFactory) -> Dataset:
    out = tmp_path_factory.mktemp("scoop") / "scoop"
    return generate_dataset("scooping", n_objects=2, n_trajectories=1, n_frames=3, seed=0, out=out)


def _mujoco_renderer(dataset: Dataset, trajectory: int = 0) -> render.FrameRenderer:
    try:
        return render.dataset_renderer(dataset, trajectory, backend="mujoco")
    except EnergyMarginError as error:
        pytest.skip(f"no OpenGL context on this machine: {error}")


def _is_object_orange(pixel: np.ndarray) -> bool:
    # The objects are orange (0.95, 0.55, 0.15) under the headlight: red well above blue.
    red, green, blue = (int(c) for c in pixel)
    return red > 90 and red > green and red > blue + 50


def _field(dataset: Dataset, trajectory: int, frame: int, expansions: int = 30):
    _, field = analyze_frame(
        dataset.task,
        dataset.frame(trajectory, frame),
        friction=float(dataset.arrays["friction"][trajectory]),
        drive=dataset.arrays["drive"][trajectory],
        seed=3,
        config=AnalyzerConfig(expansions=expansions),
        start_time=float(dataset.arrays["frame_time"][trajectory, frame]),
    )
    return field, likelihood(field.costs, dataset.task.config.likelihood_lambda)


@pytest.mark.parametrize(
    "velocity", [(0.1, 0.1, 0.0), (0.0, 0.5, 0.0), (0.2, 0.5, 0.8), (0.3, 0.4, -2.0), (0.0, 0.6, 5.0)]
)
def test_pushing_capture_shapes_cover_exactly_the_region(velocity: tuple[float, float, float]) -> None:
    task = get_task("pushing")
    region = SweptRegion(task.config, np.array([1.0, 0.5]), np.array(velocity))
    assert isinstance(region, DrawableRegion)
    rng = np.random.default_rng(0)
    points = np.column_stack([rng.uniform(-0.1, 2.1, (20_000, 2)), np.full(20_000, region.shapes()[0].centre[2])])
    drawn = np.zeros(len(points), dtype=bool)
    for shape in region.shapes():
        drawn |= shape.contains(points)
    clear = np.abs(region.signed_distance(points)) > 0.02
    # Away from the boundary (2 cm: the chord of the drawn arc), drawn inside means inside.
    assert np.array_equal(drawn[clear], region.contains(points)[clear])
    assert region.contains(points).sum() > 1000


def test_success_and_scooping_shapes_cover_exactly_their_regions() -> None:
    rng = np.random.default_rng(1)
    pushing = get_task("pushing").success_region()
    scooping = get_task("scooping")
    cases = [
        (
            pushing,
            np.column_stack([rng.uniform(-0.1, 2.1, (5000, 2)), np.full(5000, pushing.shapes()[0].centre[2])]),
            1e-9,
        ),
        (scooping.success_region(), rng.uniform([-0.12, -0.05, 0.0], [0.12, 0.05, 0.14], (20_000, 3)), 1e-9),
        (scooping.capture_region(None), rng.uniform([-0.12, -0.05, 0.0], [0.12, 0.05, 0.14], (20_000, 3)), 1e-9),
    ]
    for region, points, margin in cases:
        drawn = np.zeros(len(points), dtype=bool)
        for shape in region.shapes():
            drawn |= shape.contains(points)
        clear = np.abs(region.signed_distance(points)) > margin
        assert np.array_equal(drawn[clear], region.contains(points)[clear])


def test_likelihood_colours_run_from_dark_to_bright() -> None:
    scale = render.likelihood_scale(np.array([1e-12, 1e-4, 1e-2, 0.5]))
    assert scale[0] == 0.0 and scale[-1] == 1.0 and np.all(np.diff(scale) > 0)
    colours = render.viridis(scale)
    assert colours.shape == (4, 3)
    assert colours[0].sum() < colours[-1].sum()


def test_pushing_frame_shows_every_object_where_it_projects(tiny_dataset: Path) -> None:
    dataset = load_dataset(tiny_dataset)
    frame = dataset.frame(0, 1)
    field, likelihoods = _field(dataset, 0, 1)
    with _mujoco_renderer(dataset) as renderer:
        plain = renderer.render(frame, regions=False)
        assert plain.shape == (480, 640, 3) and plain.dtype == np.uint8
        centres = np.round(renderer.project(frame.object_pos)).astype(int)
        # The same camera for the full picture (the default view would also hold the tree).
        view = render.scene_view(renderer.simulator.scene, renderer.view_points(frame))
        full = renderer.render(frame, view=view, field=field, likelihoods=likelihoods)
        assert np.array_equal(np.round(renderer.project(frame.object_pos)).astype(int), centres)
    assert len(np.unique(plain.reshape(-1, 3), axis=0)) > 20
    for column, row in centres:
        assert 0 <= column < 640 and 0 <= row < 480
        assert _is_object_orange(plain[row, column]), plain[row, column]
        assert _is_object_orange(full[row, column]), full[row, column]
    # The corners are ground or wall, not object.
    assert not _is_object_orange(plain[5, 5]) and not _is_object_orange(plain[-5, -5])
    # Regions and tree points change the picture.
    assert np.mean(np.any(full != plain, axis=-1)) > 0.05


def test_tree_points_are_drawn_with_their_likelihood_colours(tiny_dataset: Path) -> None:
    dataset = load_dataset(tiny_dataset)
    frame = dataset.frame(0, 0)
    field, likelihoods = _field(dataset, 0, 0)
    with _mujoco_renderer(dataset) as renderer:
        view = render.scene_view(renderer.simulator.scene, renderer.view_points(frame, field))
        without = renderer.render(frame, view=view, regions=False)
        with_tree = renderer.render(frame, view=view, field=field, likelihoods=likelihoods, regions=False)
        # The node farthest from every object centre of the frame is not hidden inside an object.
        distance = np.linalg.norm(field.object_pos[:, :, None, :2] - frame.object_pos[None, None, :, :2], axis=-1)
        node, obj = np.unravel_index(np.argmax(distance.min(axis=-1)), distance.shape[:2])
        column, row = np.round(renderer.project(field.object_pos[node, obj][None])[0]).astype(int)
    # Clear of every object (radius 5 cm) of the frame.
    assert distance[node, obj].min() > 0.08
    expected = render.viridis(render.likelihood_scale(likelihoods))[node]
    assert not np.array_equal(with_tree[row, column], without[row, column])
    # Shading darkens a colour but keeps its hue: the brightest channel of the sphere is the
    # brightest channel of its colour map entry.
    assert int(np.argmax(with_tree[row, column])) == int(np.argmax(expected))


def test_scooping_frame_shows_every_box_where_it_projects(scooping_dataset: Dataset) -> None:
    frame = scooping_dataset.frame(0, 0)
    with _mujoco_renderer(scooping_dataset) as renderer:
        plain = renderer.render(frame, regions=False)
        centres = np.round(renderer.project(frame.object_pos)).astype(int)
        with_regions = renderer.render(frame)
    for column, row in centres:
        assert _is_object_orange(plain[row, column]), plain[row, column]
    assert np.mean(np.any(with_regions != plain, axis=-1)) > 0.05


def test_without_gl_the_projection_is_drawn_with_one_warning(
    tiny_dataset: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    dataset = load_dataset(tiny_dataset)
    monkeypatch.setenv("MUJOCO_GL", "none-such")
    monkeypatch.setattr(render, "_warned", set())
    field, likelihoods = _field(dataset, 0, 1, expansions=10)
    with render.dataset_renderer(dataset, 0) as renderer:
        assert renderer.backend == "matplotlib"
        image = renderer.render(dataset.frame(0, 1), field=field, likelihoods=likelihoods)
        renderer.render(dataset.frame(0, 2))
    with render.dataset_renderer(dataset, 1):
        pass
    assert image.shape == (480, 640, 3)
    assert float(image.std()) > 5 and len(np.unique(image.reshape(-1, 3), axis=0)) > 20
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("energy-margin: warning: no OpenGL context")
    with pytest.raises(EnergyMarginError, match="no OpenGL context"):
        render.dataset_renderer(dataset, 0, backend="mujoco")


def test_unknown_trajectory_or_frame_is_one_clear_error(tiny_dataset: Path) -> None:
    dataset = load_dataset(tiny_dataset)
    with pytest.raises(EnergyMarginError, match=r"no trajectory 5 \(trajectories 0 to 1\)"):
        render.check_trajectory(dataset, 5)
    with pytest.raises(EnergyMarginError, match=r"no frame 3 \(frames 0 to 2\)"):
        render.check_trajectory(dataset, 0, 3)


def test_png_is_written_atomically(tmp_path: Path) -> None:
    pixels = np.zeros((20, 30, 3), dtype=np.uint8)
    pixels[5:10, 5:10] = (255, 0, 0)
    render.save_png(pixels, tmp_path / "picture.png")
    import matplotlib.image

    back = matplotlib.image.imread(tmp_path / "picture.png")
    assert back.shape[:2] == (20, 30) and back[7, 7, 0] == 1.0
    assert [p.name for p in tmp_path.iterdir()] == ["picture.png"]


def test_objects_drawn_inside_a_region_are_the_objects_inside_it(tiny_dataset: Path, scooping_dataset: Dataset) -> None:
    # The report's check: an object whose centre is drawn inside a region lies in it, and back.
    for dataset in (load_dataset(tiny_dataset), scooping_dataset):
        task = dataset.task
        checked = 0
        for trajectory in range(dataset.n_trajectories):
            for k in range(dataset.n_frames):
                frame = dataset.frame(trajectory, k)
                for region in (task.capture_region(frame), task.success_region()):
                    drawn = render.drawn_inside(region, frame.object_pos)
                    clear = np.abs(region.signed_distance(frame.object_pos)) > 0.02
                    assert np.array_equal(drawn[clear], region.contains(frame.object_pos)[clear])
                    checked += int(clear.sum())
        assert checked > 0
    # A region without shapes has no drawing to check.
    assert render.drawn_inside(_Everywhere(), np.zeros((2, 3))) is None


class _Everywhere:
    def contains(self, positions: np.ndarray, velocities: np.ndarray | None = None) -> np.ndarray:
        return np.ones(np.shape(positions)[:-1], dtype=bool)


def test_a_region_without_shapes_is_drawn_as_grid_cells() -> None:
    cells = render.region_shapes(_Everywhere(), np.array([[0.0, 0.0, 0.0], [1.0, 2.0, 1.0]]), height=0.1)
    assert len(cells) == 48 * 48
    assert all(cell.centre[2] == 0.1 and cell.kind == "box" for cell in cells)


def test_a_picture_frames_the_robot_parts_near_the_objects_only() -> None:
    from energy_margin.report.render import near_objects

    objects = np.array([[0.0, 0.3, 0.03], [0.1, 0.35, 0.03]])
    paddle, arm_base, floor_far = [0.05, 0.2, 0.05], [0.0, -0.6, 0.1], [3.0, 3.0, 0.0]
    kept = near_objects(np.array([paddle, arm_base, floor_far]), objects)
    assert kept.tolist() == [paddle]
