"""``evaluate --explain``: the failed trajectories' account in the text and in the JSON."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from energy_margin.cli import main
from energy_margin.data.dataset import load_dataset
from score_files import write_scores


@pytest.fixture
def scored(tiny_dataset: Path, rewrite_frames: Callable[..., None]) -> Path:
    """The tiny dataset, object 0 of trajectory 0 moved away at the last frame (it fails), with scores."""
    dataset = load_dataset(tiny_dataset)
    positions = dataset.arrays["object_pos"].copy()
    positions[0, -1, 0] = [-2.0, 4.0, 0.0]
    in_success = dataset.arrays["in_success"].copy()
    in_success[0, -1] = False
    captured = dataset.arrays["captured"].copy()
    captured[0, -1] = False
    rewrite_frames(tiny_dataset, object_pos=positions, in_success=in_success, captured=captured)
    grid = np.linspace(0.0, 1.0, dataset.n_trajectories * dataset.n_frames).reshape(captured.shape)
    write_scores(tiny_dataset, grid, grid[::-1])
    return tiny_dataset


def test_explain_prints_each_failed_trajectory(scored: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["evaluate", str(scored), "--explain", "--resamples", "0"]) == 0
    out = capsys.readouterr().out
    assert "failed trajectories: 2" in out
    assert "trajectory 0: capture lost at frame 2;" in out
    assert "  object 0 left the capture region at frame 2 (t = 2.000 s) at (-2.000, 4.000, 0.000) m" in out
    assert "  object 0 missed the success region at frame 2 (t = 2.000 s) at (-2.000, 4.000, 0.000) m" in out
    # Object 1 of trajectory 0 stays inside: it is not named in trajectory 0's block.
    block = out.split("trajectory 0:")[1].split("trajectory 1:")[0]
    assert "object 1" not in block


def test_without_explain_nothing_is_explained(scored: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["evaluate", str(scored), "--resamples", "0"]) == 0
    assert "failed trajectories" not in capsys.readouterr().out
    assert main(["evaluate", str(scored), "--resamples", "0", "--json"]) == 0
    assert "explanations" not in json.loads(capsys.readouterr().out)


def test_explain_json_holds_the_explanations(scored: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["evaluate", str(scored), "--explain", "--resamples", "0", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    explanations = result["explanations"]
    assert [item["trajectory"] for item in explanations] == [0, 1]
    first = explanations[0]
    assert first["capture_lost_frame"] == 2
    assert first["capture_needed"] == 2 and first["success_needed"] == 2
    assert [(e["kind"], e["object"], e["frame"], e["name"]) for e in first["events"]] == [
        ("left_capture", 0, 2, "object0"),
        ("missed_success", 0, 2, "object0"),
    ]
    assert first["events"][0]["time_s"] == pytest.approx(2.0)
    assert first["events"][0]["position"] == pytest.approx([-2.0, 4.0, 0.0])
