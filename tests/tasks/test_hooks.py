"""A task registered from outside the core gets plots, reports, imports and sweeps through the task hooks."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from energy_margin import tasks
from energy_margin.data.generate import generate_dataset
from energy_margin.data.reference import import_reference, read_reference, reference_tasks
from energy_margin.design.sweep import design_grid
from energy_margin.errors import EnergyMarginError
from energy_margin.experiments.study import TASKS, StudyTask
from energy_margin.planning.tree import CostField
from energy_margin.report import estimate, plots
from energy_margin.tasks import (
    PushingTask,
    ReferenceLayout,
    SceneTask,
    ScoopingTask,
    get_task,
    register_task,
    task_class,
)


class Shoving(PushingTask):
    """The pushing task under another name, as a package outside the core would register it."""

    name = "shoving"


@pytest.fixture
def shoving(monkeypatch: pytest.MonkeyPatch) -> Iterator[str]:
    """``Shoving`` registered for one test (the registry is restored afterwards)."""
    monkeypatch.setattr(tasks, "_REGISTRY", dict(tasks._REGISTRY))
    register_task(Shoving)
    yield Shoving.name


@pytest.fixture
def shoving_set(shoving: str, tmp_path: Path) -> Path:
    """A generated dataset of the registered task: 1 trajectory x 3 frames, 2 objects."""
    out = tmp_path / "shoving"
    generate_dataset(shoving, n_objects=2, n_trajectories=1, n_frames=3, seed=0, out=out)
    return out


def test_hooks_have_defaults_for_any_task() -> None:
    task = ScoopingTask()
    assert task.planar is False
    assert task.default_objects == task.typical_objects == 5
    assert ScoopingTask.design_aliases()[0].name == "finger_stiffness"
    frame = _first_frame(task, 2)
    # The derived shape: the kinds of the solids that draw the region (the scooping footprint box).
    assert task.capture_region_shape(frame) == "box"
    assert SceneTask.reference_layout is None
    assert SceneTask.design_aliases() == ()
    assert SceneTask.region_caption == ""


def test_the_built_in_values_are_kept() -> None:
    pushing = get_task("pushing")
    assert pushing.planar is True
    assert (pushing.default_objects, get_task("scooping").default_objects) == (10, 5)
    assert {"pushing": StudyTask(objects=10, seed=0), "scooping": StudyTask(objects=5, seed=0)} == TASKS
    # 11 stills and a video at 30 fps of a 2 s (pushing) and a 2.3 s (scooping) roll-out.
    assert [estimate._report_pictures(name) for name in ("pushing", "scooping")] == [11 + 61, 11 + 70]
    assert reference_tasks() == {"PlanePushMulti": "pushing", "GripperMulti": "scooping"}


def test_a_registered_task_has_the_pushing_hooks(shoving: str) -> None:
    task = get_task(shoving)
    assert task_class(shoving) is Shoving
    assert task.planar is True
    assert task.region_caption == PushingTask.region_caption != ""
    assert [alias.name for alias in Shoving.design_aliases()] == ["pusher_width"]
    assert estimate.calibration_objects(shoving) == 10
    assert estimate._report_pictures(shoving) == estimate._report_pictures("pushing")
    # Their files still import as the task that declares the layout, unless the variant is asked for.
    assert reference_tasks()["PlanePushMulti"] == "pushing"


def test_the_report_names_the_capture_region_shape_through_the_hook(shoving: str) -> None:
    task = get_task(shoving)
    frame = _first_frame(task, 2)
    assert task.capture_region_shape(frame) == "disc"  # the pusher starts at rest
    moving = dataclasses.replace(frame, robot_v=np.array([0.0, 0.5, 0.0, 0.0]))
    assert task.capture_region_shape(moving) == "sector"
    assert get_task("pushing").capture_region_shape(moving) == "sector"


def test_plots_draw_a_registered_planar_task_from_the_top(
    shoving_set: Path, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    pytest.importorskip("matplotlib")
    from energy_margin.data.dataset import load_dataset

    dataset = load_dataset(shoving_set)
    views: list[str] = []
    ellipses: list[Any] = []
    draw_scene = plots.draw_scene

    def recording_scene(ax: Any, simulator: Any, *, view: str) -> None:
        views.append(view)
        draw_scene(ax, simulator, view=view)

    monkeypatch.setattr(plots, "draw_scene", recording_scene)
    monkeypatch.setattr(plots, "draw_ellipse", lambda ax, points, **kwargs: ellipses.append(points))
    plots.frame_figure(dataset, 0, [0, 2], tmp_path / "frames.png")
    frame = dataset.frame(0, 1)
    field = CostField(
        costs=np.array([0.0, 0.1]),
        object_pos=np.stack([frame.object_pos, frame.object_pos + 0.01]),
        object_vel=np.zeros((2, dataset.n_objects, 6)),
        parents=np.array([-1, 0]),
        times=np.array([0.0, 0.05]),
        expansions=1,
        physics_s=0.0,
        total_s=0.0,
    )
    plots.cost_field_figure(dataset, 0, 1, field, np.array([0.5, 0.5]), tmp_path / "field.png")
    assert views == ["top", "top", "top"]
    assert len(ellipses) == 2  # the ellipse of the object centres on every frame, as for pushing
    assert (tmp_path / "frames.png").stat().st_size > 0 and (tmp_path / "field.png").stat().st_size > 0


def test_a_registered_task_sweeps_its_design_aliases(shoving: str) -> None:
    designs = design_grid(get_task(shoving), [("pusher_width", [0.4, 0.6])])
    assert [design.overrides["pusher_half_extents"][0] for design in designs] == [0.2, 0.3]
    with pytest.raises(EnergyMarginError, match="sweepable: pusher_width or a shoving setting"):
        design_grid(get_task(shoving), [("finger_stiffness_typo", [1])])


def test_a_registered_task_imports_the_authors_files(shoving: str, tmp_path: Path) -> None:
    folder = tmp_path / "ref"
    _tiny_pushing_folder(folder)
    assert read_reference(folder).task == "pushing"
    dataset = import_reference(folder, tmp_path / "out", task=shoving, drive="coast")
    assert dataset.metadata["task"] == shoving
    assert dataset.metadata["imported_drive"] == "coast"
    plain = import_reference(folder, tmp_path / "plain", drive="coast")
    for key, values in plain.arrays.items():
        np.testing.assert_array_equal(dataset.arrays[key], values)
    with pytest.raises(EnergyMarginError, match=r"is not a reference folder: .* with Task in GripperMulti"):
        import_reference(folder, tmp_path / "scoop", task="scooping")
    with pytest.raises(EnergyMarginError, match="has no import of the authors' files"):
        read_reference(folder, task="scene")


def test_the_layout_says_which_drives_a_task_accepts(shoving: str, tmp_path: Path) -> None:
    @register_task
    class Steady(PushingTask):
        name = "steady-pushing"
        reference_layout = ReferenceLayout("PlanePushMulti", 6, 6)

    folder = tmp_path / "ref"
    _tiny_pushing_folder(folder)
    with pytest.raises(EnergyMarginError, match=r"^drive coast does not apply to steady-pushing; its drives: nominal"):
        import_reference(folder, tmp_path / "out", task=Steady.name, drive="coast")
    assert import_reference(folder, tmp_path / "out", task=Steady.name).metadata["imported_drive"] == "nominal"
    # Two tasks declare the layout: the files import by default as the first by name.
    assert reference_tasks()["PlanePushMulti"] == "pushing"

    @register_task
    class Misread(ScoopingTask):
        name = "scooping-misread"
        reference_layout = ReferenceLayout("PlanePushMulti", 6, 6)

    with pytest.raises(EnergyMarginError, match="task 'scooping-misread' cannot hold their PlanePushMulti frames"):
        import_reference(folder, tmp_path / "wrong", task=Misread.name)
    layout = ScoopingTask.reference_layout
    assert layout is not None and layout.drives == ("nominal",) and layout.replays_recorded


def _first_frame(task: tasks.Task, n_objects: int) -> Any:
    trajectory = task.sample_trajectory(np.random.default_rng(0), n_objects)
    return trajectory.initial


def _tiny_pushing_folder(folder: Path) -> None:
    """1 trajectory x 2 frames, 1 object, in the authors' pushing layout."""
    folder.mkdir(parents=True)
    rows = [f"0,{frame},1.0,{0.8 + 0.1 * frame},0,0,0.1,0,1.0,{0.5 + 0.1 * frame},0,0,0.2,0" for frame in range(2)]
    files = {
        "viapoints": ["num_traj,data_id,xo,yo,thetao,vxo,vyo,omegao,xg,yg,thetag,vxg,vyg,omegag", *rows],
        "capture_labels": [
            "num_traj,data_id,capture_exists_label,capture_all_label,lateral_friction_coef",
            "0,0,1,0,0.4",
            "0,1,1,1,0.4",
        ],
        "success_labels": ["num_traj,success_all_label,success_exists_label", "0,1,1"],
    }
    for kind, lines in files.items():
        (folder / f"scripted_movement_{kind}_PlanePushMulti.csv").write_text("\n".join(lines) + "\n")
