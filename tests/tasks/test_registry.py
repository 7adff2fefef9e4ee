from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from energy_margin import tasks
from energy_margin.errors import EnergyMarginError, InvalidParameterError
from energy_margin.tasks import PushingConfig, PushingTask, available_tasks, get_task, register_task
from energy_margin.tasks.pushing import WallBand


@pytest.fixture
def private_registry(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(tasks, "_REGISTRY", dict(tasks._REGISTRY))


def test_pushing_is_registered() -> None:
    assert "pushing" in available_tasks()
    task = get_task("pushing")
    assert isinstance(task, PushingTask)
    assert task.config == PushingConfig()
    assert get_task("pushing", None).config == PushingConfig()


def test_overrides_are_applied_and_lists_become_tuples() -> None:
    task = get_task("pushing", {"drive_jitter": 0.1, "friction_range": [0.2, 0.4], "timestep": 1 / 240})
    assert isinstance(task.config, PushingConfig)
    assert task.config.drive_jitter == 0.1
    assert task.config.friction_range == (0.2, 0.4)
    assert task.config.timestep == 1 / 240
    assert task.build_scene(1, 0.3).timestep == 1 / 240


def test_config_round_trips_through_a_dictionary() -> None:
    task = get_task("pushing", {"wall_y": 1.8})
    again = get_task("pushing", task.config.to_dict())
    assert again.config == task.config
    assert WallBand(again.config).high == pytest.approx(1.8 - 0.05 + 0.1)


def test_unknown_task_is_a_user_error() -> None:
    with pytest.raises(EnergyMarginError, match="unknown task 'stacking'; available: pushing"):
        get_task("stacking")


def test_unknown_configuration_key_is_a_user_error() -> None:
    with pytest.raises(EnergyMarginError, match="unknown pushing configuration keys: bogus, nope"):
        get_task("pushing", {"nope": 1, "bogus": 2})


def test_register_a_new_task_without_touching_the_core(private_registry: None) -> None:
    @register_task
    class Wider(PushingTask):
        name = "wider-pushing"

        def within_bounds(self, object_pos: np.ndarray, object_vel: np.ndarray) -> bool:
            return True

    assert "wider-pushing" in available_tasks()
    task = get_task("wider-pushing", {"wall_y": 2.0})
    assert isinstance(task, Wider)
    assert task.config.wall_y == 2.0
    assert task.within_bounds(np.full((1, 3), 50.0), np.zeros((1, 6)))


def test_register_requires_a_name(private_registry: None) -> None:
    class Nameless(PushingTask):
        name = ""

    with pytest.raises(InvalidParameterError, match="task_class needs a non-empty `name`"):
        register_task(Nameless)
    assert "" not in available_tasks()


@pytest.mark.parametrize(
    "override",
    [
        {"wall_y": "abc"},
        {"likelihood_lambda": -1.0},
        {"friction_range": [0.3]},
        {"duration": 0.0},
        {"friction_range": [0.4, 0.1]},
        {"object_mass": float("nan")},
    ],
)
def test_bad_configuration_values_are_user_errors(override: dict[str, Any]) -> None:
    with pytest.raises(EnergyMarginError):
        get_task("pushing", override)


def test_a_recorded_configuration_keeps_the_settings_of_its_release() -> None:
    from energy_margin.tasks import get_recorded_task, get_task

    # A dataset written before `ground_contact` existed was made with the rim contacts.
    recorded = get_task("pushing").config.to_dict()
    del recorded["ground_contact"]
    assert get_recorded_task("pushing", recorded).config.ground_contact == "geometry"
    assert get_recorded_task("pushing", {**recorded, "ground_contact": "footprint"}).config.ground_contact == (
        "footprint"
    )
    assert get_task("pushing", {"ground_contact": "footprint"}).config.ground_contact == "footprint"


def test_an_old_dataset_is_analysed_with_its_own_contacts(tiny_dataset) -> None:  # type: ignore[no-untyped-def]
    import json

    from energy_margin.data.dataset import load_dataset

    path = tiny_dataset / "dataset.json"
    metadata = json.loads(path.read_text())
    metadata["task_config"]["ground_contact"] = "footprint"
    path.write_text(json.dumps(metadata))
    assert load_dataset(tiny_dataset).task.config.ground_contact == "footprint"
    metadata["task_config"].pop("ground_contact")
    path.write_text(json.dumps(metadata))
    assert load_dataset(tiny_dataset).task.config.ground_contact == "geometry"
