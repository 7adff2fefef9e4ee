"""``analyze`` on a scene file without ``lambda`` says in one line that lambda is unset and uncalibrated."""

from __future__ import annotations

from pathlib import Path

import pytest

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.run import analyze_dataset, unchosen_lambda
from energy_margin.cli import main
from energy_margin.cli.analyze import lambda_note
from energy_margin.data.dataset import load_dataset
from energy_margin.errors import InvalidParameterError

ANALYZE = ["--expansions", "5", "--no-progress", "--overwrite", "--continuation", "2"]  # no note of its own
BOUND = "max_duration = 0.1\n"


def generate(scene: Path, out: Path) -> Path:
    argv = ["generate", "--scene", str(scene), "--trajectories", "2", "--frames", "2", "--seed", "0", "--out", str(out)]
    assert main(argv) == 0
    return out


@pytest.fixture
def unset(make_scene, tmp_path: Path) -> Path:
    """A dataset of the tiny scene, whose file gives no perturbation.lambda."""
    return generate(make_scene(), tmp_path / "unset")


def test_analyze_says_lambda_is_unset_in_one_line(unset: Path, capsys: pytest.CaptureFixture[str]) -> None:
    capsys.readouterr()
    assert main(["analyze", str(unset), *ANALYZE]) == 0
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 1
    assert lines[0].startswith("note: lambda is unset and uncalibrated: scene file ")
    assert "the default 5 1/J" in lines[0]
    assert f"energy-margin calibrate {unset} --out CAL" in lines[0]
    assert "analyze DATASET --calibration CAL/calibration.json" in lines[0]


def test_a_chosen_lambda_says_nothing(unset: Path, capsys: pytest.CaptureFixture[str]) -> None:
    capsys.readouterr()
    assert main(["analyze", str(unset), *ANALYZE, "--lambda", "5"]) == 0
    assert capsys.readouterr().err == ""
    assert lambda_note(load_dataset(unset), AnalyzerConfig(likelihood_lambda=2.0)) is None
    assert unchosen_lambda(load_dataset(unset), AnalyzerConfig(likelihood_lambda=2.0)) is None
    assert unchosen_lambda(load_dataset(unset), AnalyzerConfig()) == "default"


def test_a_scene_that_sets_lambda_says_nothing(make_scene, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    scene = make_scene(replace={BOUND: BOUND + "lambda = 5.0\n"})
    dataset = generate(scene, tmp_path / "set")
    assert load_dataset(dataset).task.lambda_origin == "set"
    capsys.readouterr()
    assert main(["analyze", str(dataset), *ANALYZE]) == 0
    assert capsys.readouterr().err == ""


def test_a_derived_lambda_is_named_derived(make_scene, tmp_path: Path) -> None:
    scene = make_scene(replace={BOUND: BOUND + "derive = true\n"})
    dataset = generate(scene, tmp_path / "derived")
    task = load_dataset(dataset).task
    assert task.lambda_origin == "derived"
    note = lambda_note(load_dataset(dataset), AnalyzerConfig())
    assert note is not None
    assert f"the derived {task.config.likelihood_lambda:.3g} 1/J" in note
    assert task.config.likelihood_lambda != 5.0


def test_a_built_in_task_sets_its_lambda(tiny_dataset: Path) -> None:
    assert load_dataset(tiny_dataset).task.lambda_origin == "set"
    assert lambda_note(load_dataset(tiny_dataset), AnalyzerConfig()) is None
    assert unchosen_lambda(load_dataset(tiny_dataset), AnalyzerConfig()) is None


def test_analyze_dataset_needs_its_directory(tiny_dataset: Path) -> None:
    loaded = load_dataset(tiny_dataset)
    detached = type(loaded)(path=None, metadata=loaded.metadata, arrays=loaded.arrays)
    with pytest.raises(InvalidParameterError, match=r"^dataset was not loaded from a directory"):
        analyze_dataset(detached, AnalyzerConfig(expansions=5))
