"""A task resolved once: ``resolve_task`` and the variants ``Task.configured`` builds from the object."""

from __future__ import annotations

from pathlib import Path

import pytest

from energy_margin.errors import EnergyMarginError, InvalidParameterError
from energy_margin.tasks import get_task, resolve_task

_DESIGN = '[design]\npusher_width = { geom = "pusher", attribute = "size", index = 0, low = 0.05, high = 0.25 }\n'


def test_configured_equals_the_registry_build_of_the_same_settings() -> None:
    base = get_task("pushing", {"pusher_mass": 3.0})
    variant = base.configured({"pusher_speed_x": [0.1, 0.2], "friction_range": [0.2, 0.4]})
    assert (
        variant.config
        == get_task("pushing", {"pusher_mass": 3.0, "pusher_speed_x": [0.1, 0.2], "friction_range": [0.2, 0.4]}).config
    )
    assert base.config.pusher_speed_x != (0.1, 0.2)  # the base is unchanged
    assert base.configured({}) is base and base.configured(None) is base
    # Settings it already has change nothing: the same task, not a rebuilt one.
    assert base.configured({"pusher_mass": 3.0}) is base
    assert base.configured({"pusher_mass": 4.0}) is not base


def test_configured_refuses_a_bad_setting_naming_the_task() -> None:
    task = get_task("scooping")
    with pytest.raises(
        InvalidParameterError, match=r"unknown scooping configuration keys: no_such_setting \(task 'scooping'\)"
    ):
        task.configured({"no_such_setting": 1})
    with pytest.raises(
        InvalidParameterError, match=r"with low <= high, got \(-1.0, 2.0\) \(task 'scooping'\)"
    ) as raised:
        task.configured({"stiffness_range": [-1.0, 2.0]})
    assert raised.value.parameter == "stiffness_range"


def test_a_scene_variant_is_built_from_its_file_not_its_pinned_hashes(make_scene) -> None:  # type: ignore[no-untyped-def]
    path: Path = make_scene(append=_DESIGN)
    default = get_task("scene", {"scene_file": str(path)})
    wide = default.configured({"pusher_width": 0.2})
    assert wide.config.pusher_width == pytest.approx(0.2)
    assert (
        wide.loaded.model_sha256
        == get_task("scene", {"scene_file": str(path), "pusher_width": 0.2}).loaded.model_sha256
    )
    assert wide.loaded.model_sha256 != default.loaded.model_sha256
    # Back to the file's value: the default model again.
    assert wide.configured({"pusher_width": 0.15}).loaded.model_sha256 == default.loaded.model_sha256


def test_resolve_task_takes_a_name_or_a_task() -> None:
    by_name = resolve_task("pushing", {"pusher_mass": 2.0})
    assert by_name.config.pusher_mass == 2.0
    assert resolve_task(by_name) is by_name
    assert resolve_task(by_name, {"pusher_mass": 4.0}).config.pusher_mass == 4.0
    with pytest.raises(EnergyMarginError, match="unknown task 'no_such_task'"):
        resolve_task("no_such_task")
