"""``energy-margin learn --task / --scene``: generate, analyse and fit in one resumable work directory."""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from energy_margin.analysis import run as analysis_run
from energy_margin.cli import main
from energy_margin.cli.app import build_parser
from energy_margin.data.dataset import load_dataset
from energy_margin.data.scores_file import JOURNAL_FILE, SCORES_FILE, load_scores
from energy_margin.errors import EnergyMarginError, InvalidParameterError
from energy_margin.learning import margin_model, pipeline
from energy_margin.learning.margin_model import MarginModel, load_margin_model
from energy_margin.learning.pipeline import (
    MODEL_FILE,
    SETS_DIR,
    SETTINGS_FILE,
    LearnResult,
    learn_pipeline,
    pipeline_seeds,
)
from energy_margin.runs.lock import LOCK_FILE
from energy_margin.runs.npz import read_npz
from tiny_scene import write_tiny_scene

# Tiny regressors: the tests check the mechanism, not the fit (which then stops before converging).
pytestmark = pytest.mark.filterwarnings("ignore::sklearn.exceptions.ConvergenceWarning")
#: The tiny pipeline: pushing with 2 and 3 objects, 3 trajectories x 3 frames, 10 expansions per frame.
TINY: dict[str, Any] = {
    "task": "pushing",
    "objects": [2, 3],
    "n_trajectories": 3,
    "n_frames": 3,
    "expansions": 10,
    "seed": 0,
    "hidden": (8,),
    "max_iter": 40,
    "kind": "mlp",
}
CLI_TINY = ["--task", "pushing", "--objects", "2,3", "--trajectories", "3", "--frames", "3", "--expansions", "10"]


def run_tiny(work: Path, out: Path, **changes: Any) -> LearnResult:
    return learn_pipeline(work, out, **{**TINY, **changes}, log=lambda line: None)


def predictions(model: MarginModel, work: Path) -> np.ndarray:
    """Both predicted scores of every frame of every set of ``work``."""
    rows = []
    for directory in sorted((work / SETS_DIR).iterdir()):
        dataset = load_dataset(directory)
        frames = [dataset.frame(t, k) for t in range(dataset.n_trajectories) for k in range(dataset.n_frames)]
        rows.append(np.stack(model.predict(dataset.task, frames), axis=1))
    return np.concatenate(rows)


def regressor_arrays(path: Path) -> dict[str, np.ndarray]:
    return {name: value for name, value in read_npz(path).items() if name.startswith("regressor.")}


def file_stamps(work: Path) -> dict[str, tuple[int, int]]:
    """(inode, mtime) of every data file of every set: an atomic rewrite changes the inode, a write the mtime.

    Not of ``analysis.json``: every run of an analysis rewrites its settings (the same ones).
    """
    stamps = {}
    for path in sorted((work / SETS_DIR).rglob("*")):
        if path.is_file() and path.name != "analysis.json":
            status = path.stat()
            stamps[str(path.relative_to(work))] = (status.st_ino, status.st_mtime_ns)
    return stamps


def assert_same_scores(directory: Path, other: Path) -> None:
    """The two scores.csv hold the same scores of the same frames (their timing columns aside)."""
    one, two = load_scores(directory), load_scores(other)
    assert len(one["trajectory"]) == 9
    for column in ("trajectory", "frame", "capture_score", "success_score", "nodes", "expansions", "seed"):
        np.testing.assert_array_equal(one[column], two[column])


def cli(args: list[str]) -> int:
    """``main(args)``, with argparse's exit status for an argument it refuses."""
    try:
        return main(args)
    except SystemExit as exit_:
        return int(exit_.code or 0)


@pytest.fixture(scope="module")
def baseline(tmp_path_factory: pytest.TempPathFactory) -> LearnResult:
    """The tiny pipeline run once, never modified: copy its work directory to rerun it."""
    root = tmp_path_factory.mktemp("pipeline")
    return run_tiny(root / "work", root / "model.npz")


def copy_work(baseline: LearnResult, tmp_path: Path) -> Path:
    work = tmp_path / "work"
    shutil.copytree(baseline.work, work)  # copy2 keeps the mtimes
    return work


def test_pipeline_writes_a_model_that_loads(baseline: LearnResult) -> None:
    work = baseline.work
    assert baseline.out.is_file() and (work / MODEL_FILE).read_bytes() == baseline.out.read_bytes()
    loaded = load_margin_model(baseline.out, task_name="pushing")
    assert loaded.n_objects_range == (2, 3) and loaded.kind == "mlp"
    np.testing.assert_array_equal(predictions(loaded, work), predictions(baseline.model, work))
    assert [item.name for item in baseline.sets] == ["objects-2", "objects-3"]
    for item in baseline.sets:
        dataset = load_dataset(item.directory)
        assert (dataset.n_objects, dataset.n_trajectories, dataset.n_frames) == (item.objects, 3, 3)
        assert dataset.metadata["seed"] == item.generation_seed
        assert (item.directory / SCORES_FILE).is_file() and item.generated and item.analysed
        analysis = json.loads((item.directory / "analysis.json").read_text())
        assert analysis["seed"] == item.analysis_seed and analysis["analyzer"]["expansions"] == 10
    settings = json.loads((work / SETTINGS_FILE).read_text())
    assert settings["objects"] == [2, 3] and settings["fit_seed"] == baseline.fit_seed == baseline.report.seed
    assert not baseline.resumed and not (work / LOCK_FILE).exists()
    assert baseline.report.n_trajectories == {"train": 4, "held_out": 2}


def test_seeds_come_from_seed_sequence_spawn() -> None:
    fit, sets = pipeline_seeds(7, 3)
    children = np.random.SeedSequence(7).spawn(4)
    assert fit == int(children[0].generate_state(1, np.uint32)[0])
    for (generation, analysis), child in zip(sets, children[1:], strict=True):
        expected = [int(c.generate_state(1, np.uint32)[0]) for c in child.spawn(2)]
        assert [generation, analysis] == expected
    # A set's seeds depend on its position, not on how many sets follow; all seeds differ.
    assert pipeline_seeds(7, 1)[1] == sets[:1] and pipeline_seeds(7, 1)[0] == fit
    flat = [fit, *(s for pair in sets for s in pair)]
    assert len(set(flat)) == len(flat)
    assert pipeline_seeds(8, 3) != (fit, sets)


@pytest.mark.slow
def test_rerun_resumes_without_regenerating(baseline: LearnResult, tmp_path: Path) -> None:
    work = copy_work(baseline, tmp_path)
    out = tmp_path / "model.npz"
    shutil.copyfile(work / MODEL_FILE, out)  # the model this work directory wrote
    before = file_stamps(work)
    assert len(before) == 8 and "sets/objects-3/frames.npz" in before
    lines: list[str] = []
    result = learn_pipeline(work, out, **TINY, log=lines.append)
    assert file_stamps(work) == before
    assert result.resumed and not any(item.generated or item.analysed for item in result.sets)
    assert any("already generated" in line for line in lines) and any("already analysed" in line for line in lines)
    # The fit runs again, from the same scores with the same seed: the same model.
    np.testing.assert_array_equal(predictions(result.model, work), predictions(baseline.model, baseline.work))
    for name, value in regressor_arrays(out).items():
        np.testing.assert_array_equal(value, regressor_arrays(baseline.out)[name])


@pytest.mark.slow
def test_interrupted_run_continues(baseline: LearnResult, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    work, out = tmp_path / "work", tmp_path / "model.npz"
    real = analysis_run.analyze

    def killed_during_second_set(directory: Path, *args: Any, **kwargs: Any) -> Path:
        path = real(directory, *args, **kwargs)
        if Path(directory).name == "objects-3":
            # As a kill mid-analysis leaves it: no scores.csv, part of the journal.
            path.unlink()
            journal = Path(directory) / JOURNAL_FILE
            journal.write_text("".join(journal.read_text().splitlines(keepends=True)[:4]))
            raise KeyboardInterrupt
        return path

    monkeypatch.setattr(pipeline, "analyze", killed_during_second_set)
    with pytest.raises(KeyboardInterrupt):
        run_tiny(work, out)
    assert not out.exists() and not (work / MODEL_FILE).exists() and not (work / LOCK_FILE).exists()
    kept = {k: v for k, v in file_stamps(work).items() if "objects-2" in k or k.endswith("frames.npz")}
    monkeypatch.setattr(pipeline, "analyze", real)
    result = run_tiny(work, out)
    assert result.resumed
    assert [(item.generated, item.analysed) for item in result.sets] == [(False, False), (False, True)]
    assert {k: v for k, v in file_stamps(work).items() if k in kept} == kept
    # The scores and the model are those of the uninterrupted run.
    for item, first in zip(result.sets, baseline.sets, strict=True):
        assert_same_scores(item.directory, first.directory)
    np.testing.assert_array_equal(predictions(result.model, work), predictions(baseline.model, baseline.work))


def test_changed_settings_are_refused(baseline: LearnResult, tmp_path: Path) -> None:
    work = copy_work(baseline, tmp_path)
    settings = (work / SETTINGS_FILE).read_text()
    before = file_stamps(work)
    out = tmp_path / "other.npz"
    with pytest.raises(EnergyMarginError, match=r"trajectories: 3 there, 4 now.*`overwrite=True`.*`work`") as error:
        run_tiny(work, out, n_trajectories=4)
    assert "\n" not in str(error.value)
    with pytest.raises(EnergyMarginError, match=r"objects: \[2, 3\] there, \[3, 2\] now"):
        run_tiny(work, out, objects=[3, 2])
    with pytest.raises(EnergyMarginError, match=r"analyzer.expansions: 10 there, 20 now"):
        run_tiny(work, out, expansions=20)
    with pytest.raises(EnergyMarginError, match=r"seed: 0 there, 1 now"):
        run_tiny(work, out, seed=1)
    assert (work / SETTINGS_FILE).read_text() == settings and file_stamps(work) == before
    assert not out.exists()


@pytest.mark.slow
def test_fit_settings_reuse_the_sets_and_overwrite_starts_afresh(baseline: LearnResult, tmp_path: Path) -> None:
    work = copy_work(baseline, tmp_path)
    before = file_stamps(work)
    options = {key: value for key, value in TINY.items() if key not in ("hidden", "max_iter", "kind")}
    lines: list[str] = []
    result = learn_pipeline(work, tmp_path / "boosting.npz", **options, kind="boosting", max_iter=8, log=lines.append)
    assert result.resumed and file_stamps(work) == before
    assert load_margin_model(tmp_path / "boosting.npz").kind == "boosting"
    # --overwrite replaces a run of other settings: the sets are generated again.
    result = run_tiny(work, tmp_path / "four.npz", n_trajectories=4, overwrite=True)
    assert not result.resumed and all(item.generated and item.analysed for item in result.sets)
    assert load_dataset(work / SETS_DIR / "objects-2").n_trajectories == 4


@pytest.mark.slow
def test_same_seed_same_model_and_another_seed_another(baseline: LearnResult, tmp_path: Path) -> None:
    again = run_tiny(tmp_path / "again", tmp_path / "again.npz")
    first, second = regressor_arrays(baseline.out), regressor_arrays(again.out)
    assert first.keys() == second.keys() and first
    for name in first:
        np.testing.assert_array_equal(first[name], second[name])
    np.testing.assert_array_equal(predictions(again.model, again.work), predictions(baseline.model, baseline.work))
    other = run_tiny(tmp_path / "other", tmp_path / "other.npz", seed=1)
    assert [s.generation_seed for s in other.sets] != [s.generation_seed for s in baseline.sets]
    assert not np.array_equal(
        load_dataset(other.sets[0].directory).arrays["object_pos"],
        load_dataset(baseline.sets[0].directory).arrays["object_pos"],
    )


@pytest.mark.slow
def test_workers_do_not_change_the_scores(baseline: LearnResult, tmp_path: Path) -> None:
    parallel = run_tiny(tmp_path / "two", tmp_path / "two.npz", workers=2)
    for item, first in zip(parallel.sets, baseline.sets, strict=True):
        assert_same_scores(item.directory, first.directory)
    np.testing.assert_array_equal(
        predictions(parallel.model, parallel.work), predictions(baseline.model, baseline.work)
    )


def test_cli_runs_the_pipeline_and_resumes(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    work, out = tmp_path / "work", tmp_path / "model.npz"
    args = ["learn", *CLI_TINY, "--work", str(work), "--out", str(out), "--kind", "boosting"]
    assert cli([*args, "--json"]) == 0
    captured = capsys.readouterr()
    report = json.loads(captured.out)
    assert report["out"] == str(out) and report["work"] == str(work) and report["kind"] == "boosting"
    assert [s["name"] for s in report["sets"]] == ["objects-2", "objects-3"]
    assert all(s["generated"] and s["analysed"] for s in report["sets"])
    assert "learn [2/2] objects-3: generated 3 trajectories x 3 frames" in captured.err
    assert load_margin_model(out, task_name="pushing").kind == "boosting"
    # The same command again: nothing generated or analysed, the model this work wrote replaced.
    assert cli(args) == 0
    captured = capsys.readouterr()
    assert "already analysed" in captured.err and "held-out R²" in captured.out
    assert f"-> {out}" in captured.out
    # A model file the work directory did not write is kept unless --overwrite.
    foreign = tmp_path / "foreign.npz"
    foreign.write_bytes(b"not ours")
    assert cli([*args[:-4], "--work", str(work), "--out", str(foreign)]) == 2
    assert "already exists; pass --overwrite" in capsys.readouterr().err
    assert foreign.read_bytes() == b"not ours"


@pytest.mark.slow
def test_cli_scene_form(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    scene = write_tiny_scene(tmp_path / "scene")
    work, out = tmp_path / "work", tmp_path / "model.npz"
    args = ["learn", "--scene", str(scene), "--trajectories", "3", "--frames", "3", "--expansions", "5"]
    assert cli([*args, "--work", str(work), "--out", str(out), "--kind", "boosting", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["task"] == "scene" and [s["name"] for s in report["sets"]] == ["scene"]
    assert load_margin_model(out).task_name == "scene"
    # An edited scene file is another run.
    scene.write_text(scene.read_text().replace("duration = 1.5", "duration = 1.4"))
    assert cli([*args, "--work", str(work), "--out", str(out), "--kind", "boosting"]) == 2
    err = capsys.readouterr().err
    assert "(task_config.duration: 1.5 there, 1.4 now)" in err and err.count("\n") == 1


def test_kind_choices_come_from_the_model_module() -> None:
    commands = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    kind = next(a for a in commands.choices["learn"]._actions if a.dest == "kind")
    assert kind.choices is margin_model.KINDS


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        (["--task", "pushing", "--trajectories", "0", "--work", "W"], "--trajectories: expected an integer >= 2"),
        (["--task", "pushing", "--trajectories", "1", "--work", "W"], "--trajectories: expected an integer >= 2"),
        (["--task", "no-such-task", "--trajectories", "3", "--work", "W"], "invalid choice: 'no-such-task'"),
        (["--scene", "missing.toml", "--trajectories", "3", "--work", "W"], "scene file missing.toml does not exist"),
        (
            ["--scene", "S", "--objects", "3", "--trajectories", "3", "--work", "W"],
            "--objects does not apply to --scene",
        ),
        (["--task", "pushing", "--trajectories", "3"], "--task needs --work DIR"),
        (["--scene", "S", "--trajectories", "3"], "--scene needs --work DIR"),
        (["--task", "pushing", "--work", "W"], "--task needs --trajectories N"),
        (["D", "--task", "pushing", "--trajectories", "3", "--work", "W"], "got dataset directories and --task"),
        (["D", "--work", "W"], "--work applies to --task or --scene"),
        (["D", "--trajectories", "3"], "--trajectories applies to --task or --scene"),
        (["--task", "pushing", "--scene", "S", "--trajectories", "3", "--work", "W"], "not allowed with argument"),
        ([], "exactly one); got nothing to learn from"),
        (["--task", "pushing", "--objects", "2,2", "--trajectories", "3", "--work", "W"], "distinct numbers"),
        (["--task", "pushing", "--objects", "2,x", "--trajectories", "3", "--work", "W"], "comma list"),
    ],
)
def test_bad_input_is_one_line_and_writes_nothing(
    arguments: list[str], message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    scene = write_tiny_scene(tmp_path / "scene")
    (tmp_path / "D").mkdir()
    substitute = {"W": str(tmp_path / "work"), "S": str(scene), "D": str(tmp_path / "D")}
    missing = tmp_path / "missing.toml"
    args = [substitute.get(a, str(missing) if a == "missing.toml" else a) for a in arguments]
    before = sorted(p.name for p in tmp_path.rglob("*"))
    assert cli(["learn", *args, "--out", str(tmp_path / "model.npz")]) == 2
    err = capsys.readouterr().err
    assert message.replace("missing.toml", str(missing)) in err and err.count("\n") == 1, err
    assert sorted(p.name for p in tmp_path.rglob("*")) == before


def test_library_refuses_bad_arguments_before_writing(tmp_path: Path) -> None:
    work, out = tmp_path / "work", tmp_path / "model.npz"
    with pytest.raises(InvalidParameterError, match="trajectories must be an integer >= 2, got 1"):
        run_tiny(work, out, n_trajectories=1)
    with pytest.raises(InvalidParameterError, match="kind must be one of"):
        run_tiny(work, out, kind="forest")
    with pytest.raises(InvalidParameterError, match="objects must be distinct"):
        run_tiny(work, out, objects=[2, 2])
    with pytest.raises(EnergyMarginError, match="unknown task 'nope'"):
        run_tiny(work, out, task="nope")
    with pytest.raises(EnergyMarginError, match="exactly one"):
        run_tiny(work, out, task=None)
    scene = write_tiny_scene(tmp_path / "scene")
    with pytest.raises(EnergyMarginError, match="a scene file fixes its objects"):
        run_tiny(work, out, task=None, scene=scene)
    out.write_bytes(b"someone else's")
    with pytest.raises(EnergyMarginError, match="already exists; pass `overwrite=True`"):
        run_tiny(work, out)
    assert not work.exists() and out.read_bytes() == b"someone else's"
