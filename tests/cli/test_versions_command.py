"""``analyze``, ``evaluate`` and ``check`` on a dataset or scores made under another engine version."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import mujoco
import pytest

from energy_margin.cli import main
from energy_margin.data.dataset import METADATA_FILE
from energy_margin.data.scores_file import CONFIG_FILE
from energy_margin.runs.directory import run_versions
from releases import OTHER_MUJOCO
from tiny_scene import write_tiny_scene

MUJOCO = mujoco.__version__
# The tiny scene gives no lambda: --lambda sets one, so that only the version notes are left to say.
ANALYZE = ["--expansions", "5", "--no-progress", "--lambda", "5", "--continuation", "2"]  # no note of its own
EVALUATE = ["--resamples", "0", "--success-frames", "1"]


@pytest.fixture(scope="module")
def generated(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A dataset of the tiny scene file, generated once by the command line, never modified."""
    root = tmp_path_factory.mktemp("versions")
    scene = write_tiny_scene(root / "scene")
    out = root / "tiny"
    argv = ["generate", "--scene", str(scene), "--trajectories", "2", "--frames", "2", "--seed", "0", "--out", str(out)]
    assert main(argv) == 0
    return out


@pytest.fixture
def dataset(generated: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> Path:
    target = tmp_path / "tiny"
    shutil.copytree(generated, target)
    capsys.readouterr()
    return target


def set_versions(path: Path, **versions: str) -> None:
    """Set entries of the versions record of the JSON file ``path``."""
    document = json.loads(path.read_text())
    document["versions"].update(versions)
    path.write_text(json.dumps(document))


def note(dataset: Path) -> str:
    return (
        f"note: {dataset} was generated with MuJoCo {OTHER_MUJOCO}; this is MuJoCo {MUJOCO}: "
        "frames and scores can differ between engine versions\n"
    )


def test_the_same_versions_say_nothing(dataset: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["analyze", str(dataset), *ANALYZE]) == 0
    assert main(["evaluate", str(dataset), *EVALUATE]) == 0
    assert main(["check", str(dataset)]) == 0
    captured = capsys.readouterr()
    assert captured.err == "" and "warning" not in captured.out


def test_analyze_records_its_versions(dataset: Path) -> None:
    assert main(["analyze", str(dataset), *ANALYZE]) == 0
    assert json.loads((dataset / CONFIG_FILE).read_text())["versions"] == run_versions("mujoco")


def test_analyze_and_evaluate_note_a_dataset_of_another_mujoco_in_one_line(
    dataset: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    set_versions(dataset / METADATA_FILE, mujoco=OTHER_MUJOCO)
    assert main(["analyze", str(dataset), *ANALYZE]) == 0
    captured = capsys.readouterr()
    assert captured.err == note(dataset)
    assert captured.out == f"wrote {dataset / 'scores.csv'}\n"
    # The scores are this MuJoCo's, the frames another's: evaluate names both, in one line.
    assert main(["evaluate", str(dataset), *EVALUATE]) == 0
    captured = capsys.readouterr()
    assert captured.err == (
        f"note: {dataset / 'scores.csv'} was computed with MuJoCo {MUJOCO}; {dataset} was generated with MuJoCo "
        f"{OTHER_MUJOCO}: frames and scores can differ between engine versions\n"
    )
    assert "positive rate" in captured.out


def test_evaluate_notes_a_dataset_of_another_mujoco(dataset: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["analyze", str(dataset), *ANALYZE]) == 0
    # Frames and scores both of another release: only the installed MuJoCo differs.
    set_versions(dataset / METADATA_FILE, mujoco=OTHER_MUJOCO)
    set_versions(dataset / CONFIG_FILE, mujoco=OTHER_MUJOCO)
    capsys.readouterr()
    assert main(["evaluate", str(dataset), *EVALUATE]) == 0
    assert capsys.readouterr().err == note(dataset)


def test_evaluate_notes_scores_of_another_mujoco_than_the_frames(
    dataset: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["analyze", str(dataset), *ANALYZE]) == 0
    set_versions(dataset / CONFIG_FILE, mujoco="4.0.1" if MUJOCO != "4.0.1" else "4.0.0")
    recorded = json.loads((dataset / CONFIG_FILE).read_text())["versions"]["mujoco"]
    capsys.readouterr()
    assert main(["evaluate", str(dataset), *EVALUATE]) == 0
    assert capsys.readouterr().err == (
        f"note: {dataset / 'scores.csv'} was computed with MuJoCo {recorded}; {dataset} was generated with MuJoCo "
        f"{MUJOCO}: frames and scores can differ between engine versions\n"
    )


def test_check_lists_another_mujoco_as_a_finding_not_a_failure(
    dataset: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    set_versions(dataset / METADATA_FILE, mujoco=OTHER_MUJOCO)
    assert main(["check", str(dataset)]) == 0
    captured = capsys.readouterr()
    assert captured.out == (
        f"warning: dataset.json: versions.mujoco: generated with MuJoCo {OTHER_MUJOCO}; this is MuJoCo {MUJOCO}: "
        f"frames and scores can differ between engine versions\n{dataset}: ok\n"
    )
    assert captured.err == ""


def test_a_dataset_without_the_record_still_works(dataset: Path, capsys: pytest.CaptureFixture[str]) -> None:
    document = json.loads((dataset / METADATA_FILE).read_text())
    del document["versions"]
    (dataset / METADATA_FILE).write_text(json.dumps(document))
    assert main(["analyze", str(dataset), *ANALYZE]) == 0
    assert main(["evaluate", str(dataset), *EVALUATE]) == 0
    assert capsys.readouterr().err == ""  # unknown versions: nothing to compare
    assert main(["check", str(dataset)]) == 0
    assert capsys.readouterr().out == (
        "warning: dataset.json: versions: not recorded (an earlier release wrote it): the engine versions of its "
        f"frames are unknown\n{dataset}: ok\n"
    )


@pytest.mark.parametrize("command", [["analyze", *ANALYZE], ["evaluate", *EVALUATE], ["check"]])
def test_a_schema_version_this_package_cannot_read_is_refused_in_one_line(
    dataset: Path, command: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    document = json.loads((dataset / METADATA_FILE).read_text())
    document.update(schema_version=2, package_version="9.0.0")
    document["versions"]["mujoco"] = "3.3.0"  # no note about a file this version cannot read
    (dataset / METADATA_FILE).write_text(json.dumps(document))
    assert main([command[0], str(dataset), *command[1:]]) == 2
    captured = capsys.readouterr()
    assert captured.err.count("\n") == 1 and captured.err.startswith("energy-margin: error: ")
    # analyze and evaluate stop with it; check lists it as its one problem (and fails in one line).
    said = captured.err if command[0] != "check" else captured.out
    assert said.count("\n") == 1
    assert "schema_version: 2 is not supported (this version of energy-margin reads 1; energy-margin 9.0.0" in said
    assert "note" not in captured.err
