"""``AnalyzerConfig(contacts=...)`` / ``analyze --contacts``: the task's fast contact model."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from energy_margin.analysis.frame import AnalyzerConfig, FrameAnalyzer, analyze_frame
from energy_margin.cli import main
from energy_margin.data.dataset import load_dataset
from energy_margin.data.generate import generate_dataset
from energy_margin.data.scores_file import CONFIG_FILE, load_scores
from energy_margin.errors import InvalidParameterError
from energy_margin.tasks import get_task, with_contacts


def test_with_contacts() -> None:
    task = get_task("pushing")
    assert with_contacts(task, "recorded") is task
    fast = with_contacts(task, "fast")
    assert (fast.config.ground_contact, fast.config.lateral_contact) == ("footprint", "sphere")
    # Every other setting is the task's own.
    assert {k: v for k, v in fast.config.to_dict().items() if not k.endswith("_contact")} == {
        k: v for k, v in task.config.to_dict().items() if not k.endswith("_contact")
    }
    assert with_contacts(fast, "fast") is fast
    with pytest.raises(InvalidParameterError, match="no fast contact model"):
        with_contacts(get_task("scooping"), "fast")
    with pytest.raises(InvalidParameterError, match="contacts"):
        with_contacts(task, "quick")


def test_config_validates_contacts() -> None:
    with pytest.raises(InvalidParameterError, match="contacts"):
        AnalyzerConfig(contacts="quick")
    with pytest.raises(InvalidParameterError, match="MuJoCo"):
        AnalyzerConfig(contacts="fast", engine="pybullet")


def test_the_analysis_simulates_the_fast_model(tiny_dataset: Path) -> None:
    analyzer = FrameAnalyzer(load_dataset(tiny_dataset), AnalyzerConfig(expansions=5, contacts="fast"), 0)
    simulator = analyzer._simulator(0.2, load_dataset(tiny_dataset).arrays["drive"][0])
    assert simulator.scene.lateral_contact == "sphere"
    assert simulator.scene.ground_contact == "footprint"


def test_cli_records_the_contact_model(tiny_dataset: Path, tmp_path: Path) -> None:
    fast = tmp_path / "fast"
    shutil.copytree(tiny_dataset, fast)
    assert main(["analyze", str(tiny_dataset), "--expansions", "40", "--no-progress"]) == 0
    assert main(["analyze", str(fast), "--expansions", "40", "--contacts", "fast", "--no-progress"]) == 0
    recorded = json.loads((fast / CONFIG_FILE).read_text())
    assert recorded["analyzer"]["contacts"] == "fast"
    assert recorded["analysis_task_config"]["lateral_contact"] == "sphere"
    assert recorded["task_config"]["lateral_contact"] == "geometry"  # the dataset's own, unchanged
    assert "analysis_task_config" not in json.loads((tiny_dataset / CONFIG_FILE).read_text())
    # Another contact model gives other trees: the scores differ (both are scores of every frame).
    assert not np.array_equal(load_scores(fast)["capture_score"], load_scores(tiny_dataset)["capture_score"])
    # Resuming with the other model is refused (another configuration), as for any setting.
    assert main(["analyze", str(fast), "--expansions", "40", "--no-progress"]) == 2


def test_fast_contacts_are_deterministic(tiny_dataset: Path, tmp_path: Path) -> None:
    other = tmp_path / "other"
    shutil.copytree(tiny_dataset, other)
    assert main(["analyze", str(tiny_dataset), "--expansions", "40", "--contacts", "fast", "--no-progress"]) == 0
    arguments = ["analyze", str(other), "--expansions", "40", "--contacts", "fast", "--workers", "2", "--no-progress"]
    assert main(arguments) == 0
    for column in ("capture_score", "success_score", "nodes"):
        np.testing.assert_array_equal(load_scores(other)[column], load_scores(tiny_dataset)[column])


def test_cli_refuses_fast_contacts_without_a_model(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "scoop"
    generate_dataset("scooping", out=out, n_objects=1, n_trajectories=1, n_frames=2, seed=0)
    assert main(["analyze", str(out), "--expansions", "5", "--contacts", "fast", "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no fast contact model" in err[0]
    assert err[0].startswith("energy-margin: error: --contacts must be 'recorded'")
    assert not (out / "scores.csv").exists()


def test_a_simulator_of_the_recorded_scene_is_refused(tiny_dataset: Path) -> None:
    dataset = load_dataset(tiny_dataset)
    task, friction, drive = dataset.task, float(dataset.arrays["friction"][0]), dataset.arrays["drive"][0]
    recorded = task.make_simulator(dataset.n_objects, friction, drive, "mujoco")
    config = AnalyzerConfig(expansions=5, contacts="fast")
    with pytest.raises(InvalidParameterError, match="simulator"):
        analyze_frame(
            task, dataset.frame(0, 0), friction=friction, drive=drive, seed=0, config=config, simulator=recorded
        )
    fast = with_contacts(task, "fast").make_simulator(dataset.n_objects, friction, drive, "mujoco")
    scores, _ = analyze_frame(
        task, dataset.frame(0, 0), friction=friction, drive=drive, seed=0, config=config, simulator=fast
    )
    assert scores.expansions == 5
