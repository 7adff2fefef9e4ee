"""The engine-version record of every run's settings file (energy_margin.runs.versions)."""

from __future__ import annotations

import importlib.metadata
import json
from pathlib import Path

import mujoco
import numpy as np
import pytest

from energy_margin import __version__
from energy_margin.runs import RunSpec, open_run, run_directory
from energy_margin.runs.versions import engine_difference, engine_versions, recorded_versions

SPEC = RunSpec(contents="results", settings_file="run.json", outputs=("rows.csv",))
KEYED = RunSpec(contents="episodes", settings_file="control.json", settings_key="settings")


def test_engine_versions_name_the_engine_and_the_installed_libraries() -> None:
    assert engine_versions() == {"engine": "mujoco", "mujoco": mujoco.__version__, "numpy": np.__version__}
    assert engine_versions("mujoco") == engine_versions()


def test_pybullet_is_recorded_only_when_it_is_the_engine() -> None:
    versions = engine_versions("pybullet")
    try:
        expected = importlib.metadata.version("pybullet")
    except importlib.metadata.PackageNotFoundError:
        expected = "not installed"
    assert versions == {
        "engine": "pybullet",
        "mujoco": mujoco.__version__,
        "numpy": np.__version__,
        "pybullet": expected,
    }


def test_a_missing_or_malformed_record_is_unknown() -> None:
    assert recorded_versions({"versions": {"mujoco": "3.3.0"}}) == {"mujoco": "3.3.0"}
    assert recorded_versions({}) is None
    assert recorded_versions({"versions": "3.3.0"}) is None
    assert recorded_versions({"versions": {"mujoco": 3}}) is None
    assert recorded_versions([1]) is None


def test_engine_difference_compares_mujoco_then_pybullet_of_a_pybullet_record() -> None:
    now = {"engine": "mujoco", "mujoco": "4.0.0", "numpy": "2.4.6"}
    assert engine_difference({**now, "mujoco": "3.3.0"}, now) == ("MuJoCo", "3.3.0", "4.0.0")
    assert engine_difference({**now, "numpy": "1.26.4"}, now) is None  # numpy moves no frame
    assert engine_difference({"engine": "mujoco"}, now) is None  # a library one record lacks
    bullet = {"engine": "pybullet", "mujoco": "4.0.0", "pybullet": "3.2.5"}
    assert engine_difference(bullet, {**bullet, "pybullet": "3.2.7"}) == ("PyBullet", "3.2.5", "3.2.7")
    assert engine_difference({**bullet, "pybullet": "3.2.7"}, now) is None  # this install runs no PyBullet


def test_every_settings_file_records_the_versions(tmp_path: Path) -> None:
    expected = {"energy_margin": __version__, "engine": "mujoco", "mujoco": mujoco.__version__, "numpy": np.__version__}
    with run_directory(tmp_path / "plain", SPEC, {"seed": 0}):
        assert json.loads((tmp_path / "plain" / "run.json").read_text())["versions"] == expected
    # Settings under a key: the record sits beside them, and stays there when the run adds a summary.
    with run_directory(tmp_path / "keyed", KEYED, {"seed": 0}) as run:
        run.write_settings({"summary": {"rate": 0.5}})
    stored = json.loads((tmp_path / "keyed" / "control.json").read_text())
    assert stored == {"settings": {"seed": 0}, "summary": {"rate": 0.5}, "versions": expected}
    # A settings entry of that name is replaced by the run's record.
    with run_directory(tmp_path / "given", SPEC, {"seed": 0, "versions": {"mujoco": "0"}}) as run:
        assert "versions" not in run.settings
    assert json.loads((tmp_path / "given" / "run.json").read_text())["versions"] == expected


def test_the_engine_of_the_run_is_recorded(tmp_path: Path) -> None:
    with run_directory(tmp_path, SPEC, {"seed": 0}, engine="pybullet"):
        versions = json.loads((tmp_path / "run.json").read_text())["versions"]
    assert versions["engine"] == "pybullet" and "pybullet" in versions


@pytest.mark.parametrize("spec", [SPEC, KEYED], ids=["settings file", "settings under a key"])
def test_a_run_resumes_under_other_versions_and_says_so_in_one_line(
    spec: RunSpec, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with run_directory(tmp_path, spec, {"seed": 0}):
        pass
    path = tmp_path / spec.settings_file
    document = json.loads(path.read_text())
    document["versions"]["mujoco"] = "3.3.0"
    document["versions"]["numpy"] = "1.0.0"
    path.write_text(json.dumps(document))
    capsys.readouterr()
    with run_directory(tmp_path, spec, {"seed": 0}) as run:
        assert run.resumed  # the versions decide nothing: the run resumes
    err = capsys.readouterr().err
    assert err == (
        f"note: {tmp_path} was started with MuJoCo 3.3.0; this is MuJoCo {mujoco.__version__}: "
        "results of the two versions can differ\n"
    )
    # The record is now this install's.
    assert json.loads(path.read_text())["versions"]["mujoco"] == mujoco.__version__


def test_a_run_resumed_under_the_same_versions_says_nothing(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    every = RunSpec(contents="results", settings_file="run.json")  # compared=None: every setting
    with run_directory(tmp_path, every, {"seed": 0}):
        pass
    with open_run(tmp_path, every, {"seed": 0}) as run:
        assert run.resumed
    assert capsys.readouterr().err == ""
