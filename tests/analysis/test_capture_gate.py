"""The capture gate: a frame whose own objects are not all captured scores capture 0."""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from energy_margin.analysis.frame import AnalyzerConfig, analyze_frame
from energy_margin.analysis.run import analyze
from energy_margin.analysis.scores import CAPTURE_GATES, gate_capture, region_score
from energy_margin.cli import main
from energy_margin.data.dataset import load_dataset
from energy_margin.data.generate import generate_dataset
from energy_margin.data.scores_file import CONFIG_FILE, load_scores
from energy_margin.errors import EnergyMarginError, InvalidParameterError
from energy_margin.evaluation.lambda_rescoring import rescore_lambdas
from energy_margin.tasks import all_inside


def test_gate_by_hand() -> None:
    assert gate_capture(0.7, True, "current") == 0.7
    assert gate_capture(0.7, False, "current") == 0.0
    assert gate_capture(0.7, False, "none") == 0.7
    assert CAPTURE_GATES == ("current", "none")
    with pytest.raises(InvalidParameterError, match="capture_gate must be one of"):
        gate_capture(0.7, False, "root")
    with pytest.raises(InvalidParameterError, match="capture_gate must be one of"):
        AnalyzerConfig(capture_gate="always")
    assert AnalyzerConfig().capture_gate == "current"


def test_a_frame_moved_out_of_its_capture_region_scores_capture_zero(tiny_dataset: Path) -> None:
    dataset = load_dataset(tiny_dataset)
    task = dataset.task
    inside = dataset.frame(0, 0)
    assert task.is_captured(inside)
    # One object 30 cm aside, just outside the capture region, sliding back towards it at 0.3 m/s.
    pos, vel = inside.object_pos.copy(), inside.object_vel.copy()
    pos[0, 1] += 0.3
    vel[0, 1] = -0.3
    outside = dataclasses.replace(inside, object_pos=pos, object_vel=vel)
    assert not task.is_captured(outside)
    common = {"friction": float(dataset.arrays["friction"][0]), "drive": dataset.arrays["drive"][0], "seed": 5}
    for frame, captured_now in ((inside, True), (outside, False)):
        paper, field = analyze_frame(task, frame, config=AnalyzerConfig(expansions=20, capture_gate="none"), **common)
        gated, _ = analyze_frame(task, frame, config=AnalyzerConfig(expansions=20), **common)
        lam = task.config.likelihood_lambda
        mass = region_score(field.costs, all_inside(task.capture_region(frame), field.object_pos), lam)
        assert paper.capture_score == pytest.approx(mass, abs=1e-15)
        assert gated.capture_score == (paper.capture_score if captured_now else 0.0)
        assert gated.tree_capture_score == paper.tree_capture_score == paper.capture_score  # kept beside
        # Success is not gated, and the tree is the same.
        assert gated.success_score == paper.success_score
        assert gated.nodes == paper.nodes
    assert paper.capture_score > 0.5  # its tree reaches captured states: the gate is what scores it 0


def test_gated_scores_are_the_paper_scores_times_the_k0_label(tmp_path: Path) -> None:
    # Four objects: some of the twelve frames start with an object outside the capture region.
    paper, gated = tmp_path / "paper", tmp_path / "gated"
    for directory in (paper, gated):
        generate_dataset("pushing", out=directory, n_objects=4, n_trajectories=3, n_frames=4, seed=3)
    analyze(paper, AnalyzerConfig(expansions=40, capture_gate="none", continuation=0), seed=2, progress=False)
    analyze(gated, AnalyzerConfig(expansions=40, continuation=0), seed=2, progress=False)
    dataset = load_dataset(gated)
    rows_paper, rows_gated = load_scores(paper), load_scores(gated)
    label = dataset.arrays["captured"][rows_gated["trajectory"], rows_gated["frame"]]
    assert (~label).any()
    assert rows_paper["capture_score"][~label].max() > 0.0  # the gate changes a score
    np.testing.assert_array_equal(rows_gated["capture_score"], rows_paper["capture_score"] * label)
    np.testing.assert_array_equal(rows_gated["success_score"], rows_paper["success_score"])
    # The tree's own capture score is kept beside the gated one, in both files.
    np.testing.assert_array_equal(rows_gated["tree_capture_score"], rows_paper["capture_score"])
    np.testing.assert_array_equal(rows_paper["tree_capture_score"], rows_paper["capture_score"])
    assert json.loads((gated / CONFIG_FILE).read_text())["analyzer"]["capture_gate"] == "current"


def test_an_analysis_json_from_before_the_gate_is_an_ungated_run(tiny_dataset: Path) -> None:
    analyze(tiny_dataset, AnalyzerConfig(expansions=5, capture_gate="none"), progress=False)
    path = tiny_dataset / CONFIG_FILE
    description = json.loads(path.read_text())
    del description["analyzer"]["capture_gate"]
    path.write_text(json.dumps(description))
    analyze(tiny_dataset, AnalyzerConfig(expansions=5, capture_gate="none"), progress=False)  # the same run
    with pytest.raises(EnergyMarginError, match="holds scores of other settings"):
        analyze(tiny_dataset, AnalyzerConfig(expansions=5), progress=False)


def test_lambda_rescoring_gates_like_analyze(copy_dataset: Callable[[str], Path], tmp_path: Path) -> None:
    source, direct = copy_dataset("source"), copy_dataset("direct")
    found = rescore_lambdas(source, tmp_path / "lambdas", [2.0], config=AnalyzerConfig(expansions=10), progress=False)
    analyze(direct, AnalyzerConfig(expansions=10, likelihood_lambda=2.0), progress=False)
    for column in ("capture_score", "tree_capture_score"):
        np.testing.assert_array_equal(found[2.0][column], load_scores(direct)[column])


def test_command_line_option(copy_dataset: Callable[[str], Path], capsys: pytest.CaptureFixture[str]) -> None:
    directory = copy_dataset("cli")
    assert main(["analyze", str(directory), "--expansions", "5", "--capture-gate", "none"]) == 0
    assert json.loads((directory / CONFIG_FILE).read_text())["analyzer"]["capture_gate"] == "none"
    with pytest.raises(SystemExit) as raised:
        main(["analyze", str(directory), "--capture-gate", "root"])
    assert raised.value.code == 2
    assert "--capture-gate" in capsys.readouterr().err


def test_a_record_from_before_the_gate_grows_its_frames_again_as_they_were(tmp_path: Path) -> None:
    from energy_margin.report.frame_tree import analysed_tree

    directory = tmp_path / "before"
    generate_dataset("pushing", out=directory, n_objects=4, n_trajectories=3, n_frames=4, seed=3)
    analyze(directory, AnalyzerConfig(expansions=40, capture_gate="none", continuation=0), seed=2, progress=False)
    path = directory / CONFIG_FILE
    description = json.loads(path.read_text())
    del description["analyzer"]["capture_gate"]  # written before the setting existed
    path.write_text(json.dumps(description))
    rows = load_scores(directory)
    label = load_dataset(directory).arrays["captured"][rows["trajectory"], rows["frame"]]
    lost = int(np.flatnonzero(~label & (rows["capture_score"] > 0))[0])
    tree = analysed_tree(directory, int(rows["trajectory"][lost]), int(rows["frame"][lost]))
    assert tree.scores.capture_score > 0.0  # the paper's score, as the record was written
    assert tree.matches_stored
