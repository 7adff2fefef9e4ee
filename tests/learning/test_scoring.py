"""``analyze --model``: a dataset's scores.csv from a learned margin (energy_margin.learning.scoring)."""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.run import analyze
from energy_margin.cli import analyze as analyze_command
from energy_margin.cli import main
from energy_margin.data.dataset import Dataset, load_dataset
from energy_margin.data.generate import generate_dataset
from energy_margin.data.scores_file import COLUMNS, CONFIG_FILE, JOURNAL_FILE, SCORES_FILE, header, load_scores
from energy_margin.data.validation import check_dataset
from energy_margin.errors import EnergyMarginError, InvalidParameterError
from energy_margin.evaluation.metrics import average_precision, evaluate, score_grid
from energy_margin.learning.margin_model import MarginModel, fit_margin_model
from energy_margin.learning.scoring import LEARNED_ANALYZER, predict_rows, score_dataset

pytestmark = pytest.mark.filterwarnings("ignore::sklearn.exceptions.ConvergenceWarning")
# Seed 3: both classes among the capture and the success labels, so every AP is a number.
PUSH = {"n_objects": 3, "n_trajectories": 6, "n_frames": 3, "seed": 3}


@pytest.fixture(scope="module")
def pristine(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A pushing dataset of 3 objects, 6 trajectories x 3 frames, never analysed nor modified."""
    out = tmp_path_factory.mktemp("scoring") / "push3"
    generate_dataset("pushing", out=out, **PUSH)
    return out


@pytest.fixture(scope="module")
def analysed(pristine: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The same dataset analysed with 8 expansions per frame (never modified after)."""
    out = tmp_path_factory.mktemp("scoring-tree") / "push3"
    shutil.copytree(pristine, out)
    analyze(out, AnalyzerConfig(expansions=8), seed=0, progress=False)
    return out


@pytest.fixture(scope="module")
def model_file(analysed: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[MarginModel, Path]:
    """A boosting margin fitted on the analysed dataset, and its file."""
    model, _ = fit_margin_model([load_dataset(analysed)], seed=0, kind="boosting", max_iter=8)
    path = tmp_path_factory.mktemp("scoring-model") / "push3.npz"
    model.save(path)
    return model, path


@pytest.fixture
def fresh(pristine: Path, tmp_path: Path) -> Path:
    """A private copy of the unanalysed dataset."""
    return Path(shutil.copytree(pristine, tmp_path / "fresh"))


@pytest.fixture
def tree_scored(analysed: Path, tmp_path: Path) -> Path:
    """A private copy of the tree-analysed dataset."""
    return Path(shutil.copytree(analysed, tmp_path / "tree"))


def snapshot(directory: Path) -> dict[str, bytes]:
    """Every file under ``directory`` (hidden ones included) with its contents."""
    return {str(path.relative_to(directory)): path.read_bytes() for path in directory.rglob("*") if path.is_file()}


def frames_of(dataset: Dataset) -> list:
    return [dataset.frame(t, k) for t in range(dataset.n_trajectories) for k in range(dataset.n_frames)]


def run_cli(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main(argv)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def assert_refused(code: int, err: str, *needles: str) -> None:
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and lines[0].startswith("energy-margin: error: "), err
    for needle in needles:
        assert needle in lines[0]


def test_scores_have_the_tree_columns_and_the_model_predictions(
    fresh: Path, analysed: Path, model_file: tuple[MarginModel, Path]
) -> None:
    model, path = model_file
    written = score_dataset(fresh, path, progress=False)
    assert written == fresh / SCORES_FILE
    first_line = written.read_text(encoding="utf-8").splitlines(keepends=True)[0]
    assert first_line == (analysed / SCORES_FILE).read_text(encoding="utf-8").splitlines(keepends=True)[0]
    assert first_line == header() == ",".join(COLUMNS) + "\n"
    dataset = load_dataset(fresh)
    assert check_dataset(fresh, scores=True) == []
    scores = load_scores(fresh)
    capture, success = model.predict(dataset.task, frames_of(dataset))
    np.testing.assert_allclose(score_grid(dataset, scores, "capture_score").ravel(), capture, rtol=0, atol=1e-12)
    np.testing.assert_allclose(score_grid(dataset, scores, "success_score").ravel(), success, rtol=0, atol=1e-12)
    # No tree, no physics, nothing drawn; the prediction's own time per frame.
    assert np.all(scores["nodes"] == 1) and np.all(scores["expansions"] == 0)
    assert np.all(scores["physics_s"] == 0.0) and np.all(scores["seed"] == 0)
    assert np.all(scores["runtime_s"] > 0) and np.all(scores["runtime_s"] < 1.0)
    assert not (fresh / JOURNAL_FILE).exists() and not list(fresh.glob(".*"))
    record = json.loads((fresh / CONFIG_FILE).read_text(encoding="utf-8"))
    assert record["analyzer"] == LEARNED_ANALYZER
    assert record["model"]["path"] == os.path.abspath(path)
    assert record["model"]["sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()
    assert record["model"]["kind"] == "boosting" and record["model"]["n_objects"] == [3, 3]
    assert record["dataset"] == dataset.identity() and record["task_config"] == json.loads(
        json.dumps(dataset.task.config.to_dict())
    )


def test_a_loaded_dataset_and_batches_give_the_same_scores(fresh: Path, model_file: tuple[MarginModel, Path]) -> None:
    model, path = model_file
    dataset = load_dataset(fresh)
    whole = predict_rows(model, dataset)
    batched = predict_rows(model, dataset, frames_per_call=4)
    assert list(batched) == sorted(batched) and len(batched) == dataset.n_trajectories * dataset.n_frames
    for key, row in whole.items():
        assert batched[key]["capture_score"] == pytest.approx(row["capture_score"], abs=1e-12)
        assert batched[key]["success_score"] == pytest.approx(row["success_score"], abs=1e-12)
    # One call's time is shared by its frames: 4 frames per call, 5 calls for 18 frames.
    assert len({row["runtime_s"] for row in batched.values()}) <= 5
    with pytest.raises(InvalidParameterError, match="frames_per_call"):
        predict_rows(model, dataset, frames_per_call=0)
    assert score_dataset(dataset, path, progress=False) == fresh / SCORES_FILE
    scores = load_scores(fresh)
    np.testing.assert_allclose(
        score_grid(dataset, scores, "capture_score").ravel(),
        [whole[key]["capture_score"] for key in sorted(whole)],
        rtol=0,
        atol=1e-12,
    )


def test_evaluate_reads_learned_scores(
    fresh: Path, model_file: tuple[MarginModel, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    model, path = model_file
    code, out, _ = run_cli(["analyze", str(fresh), "--model", str(path), "--no-progress"], capsys)
    assert code == 0 and out.strip() == f"wrote {fresh / SCORES_FILE}"
    dataset = load_dataset(fresh)
    capture, _ = model.predict(dataset.task, frames_of(dataset))
    result = evaluate(fresh)
    assert result.n_frames == capture.size
    assert result.capture_ap is not None and result.success_ap is not None
    assert result.capture_ap == average_precision(dataset.capture_labels(0), capture.reshape(6, 3))
    assert result.physics_per_frame_s == 0.0 and result.runtime_per_frame_s > 0
    code, out, err = run_cli(["evaluate", str(fresh), "--json"], capsys)
    assert code == 0 and err == ""
    assert json.loads(out)["capture_ap"] == result.capture_ap


@pytest.mark.parametrize(
    "options",
    [
        ["--expansions", "5"],
        ["--nodes", "10"],
        ["--workers", "2"],
        ["--converge", "0.02"],
        ["--method", "rrt"],
        ["--engine", "pybullet"],
        ["--lambda", "2"],
        ["--contacts", "fast", "--cost", "energy"],
    ],
)
def test_tree_options_are_refused_with_a_model(
    fresh: Path, model_file: tuple[MarginModel, Path], options: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    before = snapshot(fresh)
    code, _, err = run_cli(["analyze", str(fresh), "--model", str(model_file[1]), *options], capsys)
    assert_refused(code, err, "grows no tree", options[0])
    assert snapshot(fresh) == before


def test_every_analyze_option_is_shared_or_tree_only() -> None:
    parser = argparse.ArgumentParser()
    analyze_command.add_arguments(parser)
    dests = {action.dest for action in parser._actions}
    assert dests - {"help", "dataset", "seed", "overwrite", "no_progress", "model"} == set(analyze_command.TREE_ONLY)
    # The default values of the tree options are accepted with --model.
    args = parser.parse_args(["somewhere", "--workers", "1", "--engine", "mujoco", "--method", "est"])
    assert analyze_command.tree_options_given(args) == []


def test_bad_models_are_refused_in_one_line_and_nothing_is_written(
    fresh: Path, model_file: tuple[MarginModel, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _, path = model_file
    before = snapshot(fresh)
    refusals: list[tuple[Path, tuple[str, ...]]] = []
    refusals.append((tmp_path / "missing.npz", ("does not exist",)))
    garbage = tmp_path / "garbage.npz"
    garbage.write_bytes(b"not an archive at all")
    refusals.append((garbage, ("not a margin model file",)))
    # A model of another task: the header names scooping.
    foreign = tmp_path / "scooping.npz"
    with np.load(path) as archive:
        arrays = {name: archive[name] for name in archive.files}
    header_json = json.loads(arrays["header"].tobytes())
    header_json["task"] = "scooping"
    arrays["header"] = np.frombuffer(json.dumps(header_json).encode(), dtype=np.uint8)
    with foreign.open("wb") as stream:
        np.savez(stream, **arrays)
    refusals.append((foreign, ("model of task 'scooping', not 'pushing'",)))
    for model_path, needles in refusals:
        code, _, err = run_cli(["analyze", str(fresh), "--model", str(model_path), "--no-progress"], capsys)
        assert_refused(code, err, *needles)
        assert snapshot(fresh) == before
        with pytest.raises(EnergyMarginError):
            score_dataset(fresh, model_path, progress=False)
        assert snapshot(fresh) == before


def test_an_object_count_outside_the_training_range_is_refused(
    tmp_path: Path, model_file: tuple[MarginModel, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "push2"
    generate_dataset("pushing", out=out, n_objects=2, n_trajectories=1, n_frames=2, seed=0)
    before = snapshot(out)
    code, _, err = run_cli(["analyze", str(out), "--model", str(model_file[1])], capsys)
    assert_refused(code, err, "holds 2 objects", "fitted on 3")
    assert snapshot(out) == before


def test_scores_of_another_configuration_need_overwrite(
    tree_scored: Path,
    analysed: Path,
    model_file: tuple[MarginModel, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    _, path = model_file
    # Tree scores are not replaced by learned ones without --overwrite ...
    before = snapshot(tree_scored)
    assert (tree_scored / JOURNAL_FILE).exists()
    code, _, err = run_cli(["analyze", str(tree_scored), "--model", str(path)], capsys)
    assert_refused(code, err, "holds scores of other settings", "analyzer", "--overwrite")
    assert snapshot(tree_scored) == before
    # ... and are with it (the tree's journal goes with them).
    code, _, _ = run_cli(["analyze", str(tree_scored), "--model", str(path), "--overwrite", "--no-progress"], capsys)
    assert code == 0 and not (tree_scored / JOURNAL_FILE).exists()
    learned = snapshot(tree_scored)
    assert learned[SCORES_FILE] != before[SCORES_FILE]
    # A tree analysis refuses to mix its scores with learned ones.
    code, _, err = run_cli(["analyze", str(tree_scored), "--expansions", "2", "--no-progress"], capsys)
    assert_refused(code, err, "holds scores of other settings", LEARNED_ANALYZER, "--overwrite")
    assert snapshot(tree_scored) == learned
    # Another model (other file contents) is another configuration too.
    other_model, _ = fit_margin_model([load_dataset(analysed)], seed=1, kind="boosting", max_iter=3)
    other = tmp_path / "other.npz"
    other_model.save(other)
    code, _, err = run_cli(["analyze", str(tree_scored), "--model", str(other)], capsys)
    assert_refused(code, err, "holds scores of other settings", "model.sha256", "--overwrite")
    assert snapshot(tree_scored) == learned
    assert score_dataset(tree_scored, other, overwrite=True, progress=False) == tree_scored / SCORES_FILE
    record = json.loads((tree_scored / CONFIG_FILE).read_text(encoding="utf-8"))
    assert record["model"]["sha256"] == hashlib.sha256(other.read_bytes()).hexdigest()
    # The tree analysis replaces learned scores with --overwrite.
    code, _, _ = run_cli(["analyze", str(tree_scored), "--expansions", "2", "--overwrite", "--no-progress"], capsys)
    assert code == 0
    assert isinstance(json.loads((tree_scored / CONFIG_FILE).read_text(encoding="utf-8"))["analyzer"], dict)
    assert np.all(load_scores(tree_scored)["expansions"] == 2)


def test_the_same_model_resumes(
    fresh: Path, model_file: tuple[MarginModel, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _, path = model_file
    score_dataset(fresh, path, progress=False)
    finished = (fresh / SCORES_FILE).read_bytes()

    def no_prediction(*args: object, **kwargs: object) -> None:
        raise AssertionError("a finished learned analysis predicted again")

    monkeypatch.setattr("energy_margin.learning.scoring.predict_rows", no_prediction)
    # The same model again, or a copy of its file elsewhere (its contents decide, not its path).
    assert score_dataset(fresh, path, progress=False) == fresh / SCORES_FILE
    copy = tmp_path / "elsewhere" / "copy.npz"
    copy.parent.mkdir()
    shutil.copyfile(path, copy)
    assert score_dataset(fresh, copy, overwrite=False, progress=False, seed=7) == fresh / SCORES_FILE
    assert (fresh / SCORES_FILE).read_bytes() == finished
    record = json.loads((fresh / CONFIG_FILE).read_text(encoding="utf-8"))
    assert record["model"]["path"] == os.path.abspath(copy) and record["seed"] == 7
    # An interrupted run (settings written, no scores.csv) predicts every frame again.
    monkeypatch.undo()
    (fresh / SCORES_FILE).unlink()
    score_dataset(fresh, path, progress=False)
    assert (fresh / SCORES_FILE).read_bytes().splitlines()[0] == finished.splitlines()[0]
    now, then = load_scores(fresh), finished.decode().splitlines()[1:]
    assert [repr(float(c)) for c in now["capture_score"]] == [line.split(",")[2] for line in then]
