"""Tasks from installed packages: the ``energy_margin.tasks`` entry-point group."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

import energy_margin.tasks as tasks
from energy_margin.cli import main
from energy_margin.data.dataset import load_dataset

PLUGIN = '''
from energy_margin.tasks.pushing import PushingTask


class WidePushingTask(PushingTask):
    """Pushing with a wider success band: a user's task in their own package."""

    name = "wide_pushing"
'''


def _install(root: Path, entry: str) -> None:
    """A distribution on sys.path, the way pip installs one: a module and a dist-info with entry_points.txt."""
    (root / "my_plugin.py").write_text(PLUGIN)
    info = root / "my_plugin-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: my-plugin\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(f"[energy_margin.tasks]\n{entry}\n")


@pytest.fixture
def fresh_registry(monkeypatch: pytest.MonkeyPatch, tmp_path: Path):
    monkeypatch.setattr(tasks, "_REGISTRY", dict(tasks._REGISTRY))
    monkeypatch.setattr(tasks, "_BROKEN", {})
    monkeypatch.setattr(tasks, "_plugins_loaded", False)
    monkeypatch.syspath_prepend(str(tmp_path / "site"))
    (tmp_path / "site").mkdir()
    yield tmp_path / "site"
    sys.modules.pop("my_plugin", None)


def test_an_installed_task_is_found_by_the_cli(fresh_registry: Path, tmp_path: Path, capsys) -> None:
    _install(fresh_registry, "wide_pushing = my_plugin:WidePushingTask")
    assert "wide_pushing" in tasks.available_tasks()
    out = tmp_path / "data"
    argv = ["generate", "--task", "wide_pushing", "--objects", "2", "--trajectories", "1", "--frames", "2"]
    assert main([*argv, "--out", str(out)]) == 0
    assert load_dataset(out).metadata["task"] == "wide_pushing"


def test_a_broken_entry_point_is_skipped_with_a_warning_and_named_when_asked_for(fresh_registry: Path, capsys) -> None:
    _install(fresh_registry, "broken = my_plugin:NoSuchClass")
    assert "broken" not in tasks.available_tasks()
    assert "task entry point 'broken' (my_plugin:NoSuchClass) skipped" in capsys.readouterr().err
    with pytest.raises(tasks.EnergyMarginError, match="entry point that cannot be loaded"):
        tasks.get_task("broken")
