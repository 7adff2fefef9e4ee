"""The engine registry: what each engine is for, and one clear line when one cannot run here."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

from energy_margin.cli import main
from energy_margin.data.generate import generate_dataset
from energy_margin.errors import EnergyMarginError
from energy_margin.runs.versions import engine_difference, engine_versions
from energy_margin.sim import (
    ENGINE_REGISTRY,
    ENGINES,
    check_engine_device,
    get_engine,
    make_model_simulator,
    make_simulator,
)
from energy_margin.sim.mujoco_backend import MujocoSimulator
from energy_margin.sim.mujoco_model import MujocoModelSimulator
from energy_margin.tasks import get_task


def test_the_registry_names_every_engine_and_what_it_is_for() -> None:
    assert ENGINES == tuple(ENGINE_REGISTRY) == ("mujoco", "pybullet", "mujoco-warp")
    warp = get_engine("mujoco-warp")
    assert warp.devices == ("cuda", "cpu") and warp.grows_together and not warp.records
    assert get_engine("mujoco").records and not get_engine("mujoco").grows_together
    with pytest.raises(EnergyMarginError, match="unknown engine 'bullet'"):
        get_engine("bullet")


def test_a_user_model_runs_on_the_engines_that_simulate_one(tiny_scene: Path) -> None:
    task = get_task("scene", {"scene_file": str(tiny_scene)})
    simulator = task.make_simulator(2, 0.4)
    assert type(simulator) is MujocoModelSimulator
    assert [name for name, engine in ENGINE_REGISTRY.items() if engine.model_simulator] == ["mujoco", "mujoco-warp"]
    with pytest.raises(EnergyMarginError, match="engine 'pybullet' simulates built-in scenes only; a model file "
                       "runs on mujoco, mujoco-warp"):  # fmt: skip
        task.make_simulator(2, 0.4, engine="pybullet")
    with pytest.raises(EnergyMarginError, match="runs on this machine's CPU only, not on `device=cuda`"):
        make_model_simulator(simulator.model, simulator.scene, "mujoco", object_joints=[], robot_joints=[],
                             device="cuda")  # fmt: skip


def test_a_cpu_engine_takes_no_device() -> None:
    scene = get_task("pushing").build_scene(1, 0.5)
    assert isinstance(make_simulator(scene, "mujoco"), MujocoSimulator)
    with pytest.raises(EnergyMarginError, match="runs on this machine's CPU only, not on `device=cuda`"):
        make_simulator(scene, "mujoco", device="cuda")
    with pytest.raises(EnergyMarginError, match="runs on cuda, cpu, not on `device=tpu`"):
        check_engine_device("mujoco-warp", "tpu")


def test_a_missing_package_is_one_line_naming_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *args: None)
    with pytest.raises(EnergyMarginError, match=r"needs the package 'warp': pip install 'energy-margin\[gpu\]'"):
        check_engine_device("mujoco-warp", "cpu")


def test_analyze_on_a_missing_engine_or_device_is_one_line(
    tiny_dataset: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    before = sorted(path.name for path in tiny_dataset.iterdir())
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *args: None)
    code = main(["analyze", str(tiny_dataset), "--engine", "mujoco-warp", "--device", "cpu", "--batch", "8"])
    err = capsys.readouterr().err
    assert code != 0 and err.count("\n") == 1 and "pip install 'energy-margin[gpu]'" in err
    monkeypatch.undo()
    code = main(["analyze", str(tiny_dataset), "--device", "cuda"])
    err = capsys.readouterr().err
    assert code != 0 and err.count("\n") == 1 and "not on --device cuda" in err
    assert sorted(path.name for path in tiny_dataset.iterdir()) == before  # nothing half-written


def test_an_engine_of_propagations_records_no_roll_outs(tmp_path: Path) -> None:
    with pytest.raises(EnergyMarginError, match="engine 'mujoco-warp' records no roll-outs: use mujoco or pybullet"):
        generate_dataset("pushing", n_objects=1, n_trajectories=1, n_frames=2, seed=0, out=tmp_path / "d",
                         engine="mujoco-warp")  # fmt: skip
    assert not (tmp_path / "d").exists()


@pytest.mark.parametrize("command", ["generate", "reproduce", "design", "sweep"])
def test_commands_that_generate_offer_engines_that_record(command: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main([command, "--help"])
    usage = capsys.readouterr().out
    assert "--engine {mujoco,pybullet}" in " ".join(usage.split())


def test_the_versions_of_a_warp_analysis_name_warp() -> None:
    versions = engine_versions("mujoco-warp")
    assert {"engine", "mujoco", "numpy", "mujoco-warp", "warp-lang"} <= set(versions)
    before = {**versions, "warp-lang": "1.0.0"}
    if versions["warp-lang"] != "1.0.0":
        assert engine_difference(before, versions) == ("Warp", "1.0.0", versions["warp-lang"])
    assert "warp-lang" not in engine_versions("mujoco")
