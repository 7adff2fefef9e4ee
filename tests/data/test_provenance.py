"""The engine versions a dataset records, and the notes when they are not the installed ones."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import mujoco
import numpy as np
import pytest

from energy_margin.data.dataset import METADATA_FILE, load_dataset
from energy_margin.data.generate import generate_dataset
from energy_margin.data.provenance import dataset_note, read_metadata, scores_note, version_findings
from energy_margin.data.scores_file import CONFIG_FILE, SCORES_FILE
from energy_margin.data.validation import check_dataset
from energy_margin.errors import EnergyMarginError
from energy_margin.runs.versions import engine_versions
from tiny_scene import write_tiny_scene

MUJOCO = mujoco.__version__
NOTE = (
    "note: {path} was generated with MuJoCo 3.3.0; this is MuJoCo "
    + MUJOCO
    + ": frames and scores can differ between engine versions"
)


@pytest.fixture(scope="module")
def scene_dataset_source(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A dataset of the tiny scene file (2 trajectories, 2 frames), never modified."""
    root = tmp_path_factory.mktemp("provenance")
    scene = write_tiny_scene(root / "scene")
    out = root / "tiny"
    generate_dataset(
        "scene", n_objects=None, n_trajectories=2, n_frames=2, seed=0, out=out, task_config={"scene_file": str(scene)}
    )
    return out


@pytest.fixture
def scene_dataset(scene_dataset_source: Path, tmp_path: Path) -> Path:
    target = tmp_path / "tiny"
    shutil.copytree(scene_dataset_source, target)
    return target


def edit(path: Path, name: str, **versions: str | None) -> None:
    """Set (a value) or remove (``None``) entries of the versions record of a JSON file in ``path``."""
    document = json.loads((path / name).read_text())
    for key, value in versions.items():
        if value is None:
            document["versions"].pop(key, None)
        else:
            document["versions"][key] = value
    (path / name).write_text(json.dumps(document))


def drop_record(path: Path) -> None:
    """Make ``dataset.json`` look written by a release before the record."""
    document = json.loads((path / METADATA_FILE).read_text())
    del document["versions"]
    (path / METADATA_FILE).write_text(json.dumps(document))


def test_a_generated_dataset_records_the_engine_and_versions(scene_dataset: Path) -> None:
    metadata = load_dataset(scene_dataset).metadata
    assert metadata["versions"] == {"engine": "mujoco", "mujoco": MUJOCO, "numpy": np.__version__}
    assert metadata["versions"] == engine_versions(metadata["engine"])


def test_the_pushing_task_records_them_too(tiny_dataset: Path) -> None:
    assert load_dataset(tiny_dataset).metadata["versions"]["mujoco"] == MUJOCO


def test_no_note_under_the_same_versions(scene_dataset: Path) -> None:
    assert dataset_note(scene_dataset) is None
    assert version_findings(scene_dataset, load_dataset(scene_dataset).metadata) == []


def test_another_mujoco_is_one_note_and_a_finding(scene_dataset: Path) -> None:
    edit(scene_dataset, METADATA_FILE, mujoco="3.3.0")
    assert dataset_note(scene_dataset) == NOTE.format(path=scene_dataset)
    findings = version_findings(scene_dataset, load_dataset(scene_dataset).metadata)
    assert [str(finding) for finding in findings] == [
        f"dataset.json: versions.mujoco: generated with MuJoCo 3.3.0; this is MuJoCo {MUJOCO}: "
        "frames and scores can differ between engine versions"
    ]
    # check lists it as a warning, never a problem.
    warnings: list = []
    assert check_dataset(scene_dataset, overlaps=False, warnings=warnings) == []
    assert [str(w) for w in warnings] == [str(f) for f in findings]


def test_another_numpy_alone_is_no_note(scene_dataset: Path) -> None:
    edit(scene_dataset, METADATA_FILE, numpy="1.0.0")
    assert dataset_note(scene_dataset) is None


def test_a_dataset_without_the_record_loads_and_check_says_the_versions_are_unknown(scene_dataset: Path) -> None:
    drop_record(scene_dataset)
    assert load_dataset(scene_dataset).n_trajectories == 2
    assert dataset_note(scene_dataset) is None
    warnings: list = []
    assert check_dataset(scene_dataset, overlaps=False, warnings=warnings) == []
    assert [str(w) for w in warnings] == [
        "dataset.json: versions: not recorded (an earlier release wrote it): the engine versions of its frames "
        "are unknown"
    ]


def test_a_malformed_record_is_unknown_not_a_problem(scene_dataset: Path) -> None:
    document = json.loads((scene_dataset / METADATA_FILE).read_text())
    document["versions"] = "4.0.0"
    (scene_dataset / METADATA_FILE).write_text(json.dumps(document))
    assert dataset_note(scene_dataset) is None
    warnings: list = []
    assert check_dataset(scene_dataset, overlaps=False, warnings=warnings) == []
    assert [w.field for w in warnings] == ["versions"] and "is not a valid record" in warnings[0].message


def test_an_imported_set_gets_no_note(scene_dataset: Path) -> None:
    document = json.loads((scene_dataset / METADATA_FILE).read_text())
    document["imported_from"] = "/their/folder"
    document["versions"]["mujoco"] = "3.3.0"
    (scene_dataset / METADATA_FILE).write_text(json.dumps(document))
    assert dataset_note(scene_dataset) is None
    assert version_findings(scene_dataset, document) == []


def test_scores_under_another_version_than_the_frames(scene_dataset: Path) -> None:
    (scene_dataset / SCORES_FILE).write_text("")  # only analysis.json's record is read
    (scene_dataset / CONFIG_FILE).write_text(json.dumps({"versions": {**engine_versions(), "mujoco": "4.0.1"}}))
    assert scores_note(scene_dataset) == (
        f"note: {scene_dataset / SCORES_FILE} was computed with MuJoCo 4.0.1; {scene_dataset} was generated with "
        f"MuJoCo {MUJOCO}: frames and scores can differ between engine versions"
    )
    findings = version_findings(scene_dataset, load_dataset(scene_dataset).metadata)
    assert [(f.file, f.field) for f in findings] == [("analysis.json", "versions.mujoco")]
    # Scores without a record (an earlier release) are not compared.
    (scene_dataset / CONFIG_FILE).write_text(json.dumps({"seed": 0}))
    assert scores_note(scene_dataset) is None


def test_pybullet_frames_are_compared_by_pybullet(scene_dataset: Path) -> None:
    document = json.loads((scene_dataset / METADATA_FILE).read_text())
    document["engine"] = "pybullet"
    document["versions"] = {**engine_versions("pybullet"), "pybullet": "0.0.1"}
    installed = engine_versions("pybullet")["pybullet"]
    assert dataset_note(scene_dataset, metadata=document) == (
        f"note: {scene_dataset} was generated with PyBullet 0.0.1; this is PyBullet {installed}: "
        "frames and scores can differ between engine versions"
    )


@pytest.mark.parametrize("version", [2, 99])
def test_a_later_schema_version_is_refused_in_one_line(scene_dataset: Path, version: int) -> None:
    document = json.loads((scene_dataset / METADATA_FILE).read_text())
    document.update(schema_version=version, package_version="9.0.0")
    (scene_dataset / METADATA_FILE).write_text(json.dumps(document))
    with pytest.raises(EnergyMarginError) as caught:
        load_dataset(scene_dataset)
    assert str(caught.value) == (
        f"dataset {scene_dataset}: dataset.json: schema_version: {version} is not supported (this version of "
        "energy-margin reads 1; energy-margin 9.0.0 wrote it: upgrade energy-margin to read it)"
    )
    assert read_metadata(scene_dataset) is None and dataset_note(scene_dataset) is None
