"""calibrate: lambda chosen by nested cross-validated AP, grouped by trajectory; analyze --calibration."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.cli import main
from energy_margin.data.dataset import load_dataset
from energy_margin.data.generate import generate_dataset
from energy_margin.data.scores_file import CONFIG_FILE, load_scores
from energy_margin.errors import EnergyMarginError
from energy_margin.evaluation.bootstrap import Questions
from energy_margin.evaluation.calibration import CALIBRATION_FILE, Calibration, calibrate
from energy_margin.evaluation.lambda_rescoring import lambda_directory
from energy_margin.evaluation.metrics import score_grid

LAMBDAS = (0.5, 50.0)
OBJECTIVE = ("capture_ap_window2",)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Eight short pushing trajectories of 3 objects: capture two frames on has both classes."""
    out = tmp_path_factory.mktemp("calibration") / "d"
    generated = generate_dataset("pushing", n_objects=3, n_trajectories=8, n_frames=5, seed=3, out=out)
    labels = generated.capture_labels(2)
    assert labels.any() and not labels.all()
    return out


def small_calibration(dataset: Path, out: Path, **changes: Any) -> Calibration:
    """A calibration with 12 expansions a frame, 4 folds, seed 1 (``changes`` replace any of them)."""
    options: dict[str, Any] = {
        "lambdas": LAMBDAS,
        "folds": 4,
        "objective": OBJECTIVE,
        "config": AnalyzerConfig(expansions=12),
        "seed": 1,
        "resamples": 50,
        "progress": False,
        **changes,
    }
    return calibrate(dataset, out, **options)


@pytest.fixture(scope="module")
def calibrated(dataset: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, object]:
    out = tmp_path_factory.mktemp("calibration-run") / "cal"
    return out, small_calibration(dataset, out)


def test_each_fold_is_scored_at_the_lambda_chosen_without_it(dataset: Path, calibrated) -> None:  # type: ignore[no-untyped-def]
    out, result = calibrated
    data = load_dataset(dataset)
    grids = {}
    for lam in result.lambdas:
        scores = load_scores(lambda_directory(out / "lambda", "est", 12, lam))
        grids[lam] = (score_grid(data, scores, "capture_score"), score_grid(data, scores, "success_score"))
    assert result.lambdas == (0.5, 5.0, 50.0)  # the task's own lambda joins the grid
    questions = Questions(
        data,
        3,
        capture_windows={"capture_ap": 0, "capture_ap_window2": 2},
        success_spans={"success_ap": (None, None), "success_ap_first_half": (0, 2)},
    )
    every = np.arange(data.n_trajectories)
    covered = []
    for fold in result.folds:
        held = np.array(fold["trajectories"])
        train = np.setdiff1d(every, held)
        objective = {}
        for lam in result.lambdas:
            value = questions.answer(*grids[lam], train)["capture_ap_window2"]
            objective[lam] = float("-inf") if value is None else value
        best = max(objective.values())
        assert fold["likelihood_lambda"] == min(lam for lam, value in objective.items() if value == best)
        # The held-out score grids are the held trajectories' scores at the fold's choice.
        assert result.held_out_scores is not None
        for held_grid, chosen_grid in zip(result.held_out_scores, grids[fold["likelihood_lambda"]], strict=True):
            np.testing.assert_array_equal(held_grid[held], chosen_grid[held])
        covered.extend(held.tolist())
    assert sorted(covered) == list(range(data.n_trajectories))  # every trajectory held out exactly once
    assert len(result.folds) == 4
    stored = json.loads((out / CALIBRATION_FILE).read_text())
    assert stored["result"]["likelihood_lambda"] == result.likelihood_lambda
    assert "held_out_scores" not in stored["result"] and result.default_scores is not None
    np.testing.assert_array_equal(result.default_scores[0], grids[5.0][0])
    assert stored["settings"]["folds"] == 4 and stored["settings"]["objective"] == list(OBJECTIVE)
    assert set(result.verdict) == {"capture_ap", "capture_ap_window2", "success_ap", "success_ap_first_half"}


def test_a_rerun_resumes_without_growing_trees_and_gives_the_same_result(
    dataset: Path, calibrated, monkeypatch
) -> None:  # type: ignore[no-untyped-def]
    out, result = calibrated
    from energy_margin.evaluation import lambda_rescoring

    def no_growth(*args, **kwargs):  # type: ignore[no-untyped-def]
        raise AssertionError("a finished calibration grew trees again")

    monkeypatch.setattr(lambda_rescoring, "_rescore_pending", no_growth)
    again = small_calibration(dataset, out)
    assert again == result
    with pytest.raises(EnergyMarginError, match="holds a calibration of other settings"):
        small_calibration(dataset, out, folds=3)


def test_analyze_takes_the_calibrated_lambda(dataset: Path, calibrated, tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    import shutil

    out, result = calibrated
    copy = tmp_path / "copy"
    shutil.copytree(dataset, copy)
    file = str(out / CALIBRATION_FILE)
    assert main(["analyze", str(copy), "--expansions", "12", "--calibration", file, "--no-progress"]) == 0
    recorded = json.loads((copy / CONFIG_FILE).read_text())
    assert recorded["analyzer"]["likelihood_lambda"] == result.likelihood_lambda
    assert (recorded["analyzer"]["wrench_scale"], recorded["analyzer"]["duration_scale"]) == (1.0, 1.0)
    capsys.readouterr()
    assert main(["analyze", str(copy), "--calibration", file, "--lambda", "3"]) == 2
    assert "--calibration and --lambda both set lambda" in capsys.readouterr().err
    scooping = tmp_path / "scoop"
    generate_dataset("scooping", n_objects=2, n_trajectories=1, n_frames=2, seed=0, out=scooping)
    assert main(["analyze", str(scooping), "--calibration", file]) == 2
    assert "calibrates task 'pushing', not this dataset's 'scooping'" in capsys.readouterr().err
    (tmp_path / "bad.json").write_text("{}")
    assert main(["analyze", str(copy), "--calibration", str(tmp_path / "bad.json"), "--overwrite"]) == 2
    assert "is not a calibration file" in capsys.readouterr().err


def test_too_few_trajectories_or_one_class_is_refused_in_one_line(  # type: ignore[no-untyped-def]
    dataset: Path, tmp_path: Path, capsys, rewrite_frames
) -> None:
    import shutil

    assert main(["calibrate", str(dataset), "--out", str(tmp_path / "a"), "--folds", "9", "--no-progress"]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "needs at least 9 trajectories for 9 folds" in error
    assert not (tmp_path / "a").exists()
    failed = tmp_path / "failed"
    shutil.copytree(dataset, failed)
    rewrite_frames(failed, in_success=np.zeros((8, 5), dtype=bool))  # no trajectory succeeds
    assert main(["calibrate", str(failed), "--out", str(tmp_path / "b"), "--no-progress"]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "every label of success_ap_first_half" in error and "is negative" in error
    assert not (tmp_path / "b").exists()


def test_growth_scales_grow_their_own_trees_and_join_the_choice(dataset: Path, tmp_path: Path) -> None:
    out = tmp_path / "grow"
    result = small_calibration(dataset, out, lambdas=(5.0,), resamples=20, wrench_scales=(1.0, 3.0))
    assert (out / "lambda" / "w3-d1").is_dir()  # the scaled trees, beside the task's own
    assert result.wrench_scale in (1.0, 3.0) and result.duration_scale == 1.0
    assert {fold["wrench_scale"] for fold in result.folds} <= {1.0, 3.0}
    own = load_scores(lambda_directory(out / "lambda", "est", 12, 5.0))
    scaled = load_scores(lambda_directory(out / "lambda" / "w3-d1", "est", 12, 5.0))
    assert not np.array_equal(own["capture_score"], scaled["capture_score"])  # other trees
    stored = json.loads((out / CALIBRATION_FILE).read_text())
    assert stored["settings"]["growth"] == [[1.0, 1.0], [3.0, 1.0]]
    with pytest.raises(EnergyMarginError, match="wrench_scales must be positive numbers"):
        calibrate(dataset, tmp_path / "bad", wrench_scales=(0.0,), config=AnalyzerConfig(expansions=12))


def test_a_wider_wrench_bound_grows_a_different_tree(dataset: Path) -> None:
    from energy_margin.analysis.frame import analyze_frame

    data = load_dataset(dataset)
    frame = data.frame(0, 1)
    friction, drive = float(data.arrays["friction"][0]), data.arrays["drive"][0]
    own = analyze_frame(data.task, frame, friction=friction, drive=drive, seed=0, config=AnalyzerConfig(expansions=20))
    again = analyze_frame(
        data.task, frame, friction=friction, drive=drive, seed=0, config=AnalyzerConfig(expansions=20, wrench_scale=1.0)
    )
    wider = analyze_frame(
        data.task, frame, friction=friction, drive=drive, seed=0, config=AnalyzerConfig(expansions=20, wrench_scale=2.0)
    )
    assert (own[0].capture_score, own[0].success_score) == (again[0].capture_score, again[0].success_score)
    np.testing.assert_array_equal(own[1].object_pos, again[1].object_pos)
    assert not np.array_equal(own[1].object_pos, wider[1].object_pos)


def test_a_calibration_with_a_continuation_carries_it_to_analyze(dataset: Path, tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    import shutil

    out = tmp_path / "cal"
    argv = ["calibrate", str(dataset), "--out", str(out), "--folds", "4", "--expansions", "8", "--lambdas", "0.5",
            "50", "--objective", "success_ap_first_half", "--continuation", "3", "--resamples", "20",
            "--no-progress"]  # fmt: skip
    assert main(argv) == 0
    settings = json.loads((out / CALIBRATION_FILE).read_text())["settings"]["analyzer"]
    assert settings["continuation"] == 3
    copy = tmp_path / "copy"
    shutil.copytree(dataset, copy)
    file = str(out / CALIBRATION_FILE)
    assert main(["analyze", str(copy), "--expansions", "8", "--calibration", file, "--no-progress"]) == 0
    assert json.loads((copy / CONFIG_FILE).read_text())["analyzer"]["continuation"] == 3
    capsys.readouterr()
    assert main(["analyze", str(copy), "--calibration", file, "--continuation", "5", "--overwrite"]) == 2
    assert "--calibration chose lambda with --continuation 3" in capsys.readouterr().err
