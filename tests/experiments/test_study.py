"""The study: its tables, paired intervals, resume, and lambda re-scoring against a direct analysis."""

from __future__ import annotations

import csv
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import energy_margin.analysis.frame as frame_module
import energy_margin.runs.display as display_module
from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.run import analyze
from energy_margin.cli import main
from energy_margin.data.dataset import load_dataset
from energy_margin.data.generate import generate_dataset
from energy_margin.data.scores_file import load_scores
from energy_margin.errors import EnergyMarginError
from energy_margin.experiments.budget_display import BudgetDisplay
from energy_margin.experiments.study import (
    DIFFERENCE_FIELDS,
    FIELDS,
    LAMBDA_FIELDS,
    QUESTION_NAMES,
    SETTINGS_FILE,
    LambdaDisplay,
    StudyResult,
    StudyTask,
    draw_study,
    paired_difference,
    rescore_lambdas,
    run_study,
    score_questions,
    study_questions,
)

TINY_TASK = {"pushing": StudyTask(objects=3, seed=3)}  # both classes in capture and success
SMALL = {
    "tasks": ["pushing"],
    "n_trajectories": 3,
    "n_frames": 3,
    "expansions": [3],
    "methods": ["est", "montecarlo"],
    "lambdas": [1.0, 5.0],
    "lambda_expansions": 3,
    "bootstrap": 20,
    "seed": 2,
    "task_specs": TINY_TASK,
    "progress": False,
}


class CountingAnalyzeFrame:
    """Counts tree growths; raises KeyboardInterrupt at call ``stop`` (an interruption)."""

    def __init__(self, stop: int | None = None) -> None:
        self.calls = 0
        self.stop = stop
        self.real = frame_module.analyze_frame

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        self.calls += 1
        if self.stop is not None and self.calls == self.stop:
            raise KeyboardInterrupt
        return self.real(*args, **kwargs)


def _csv_header(path: Path) -> list[str]:
    with path.open(encoding="utf-8") as stream:
        return next(csv.reader(stream))


def test_study_writes_every_row_and_column(tmp_path: Path) -> None:
    lines: list[str] = []
    result = run_study(tmp_path / "study", log=lines.append, **SMALL)
    out = tmp_path / "study"
    assert _csv_header(out / "study.csv") == list(FIELDS)
    assert _csv_header(out / "study_differences.csv") == list(DIFFERENCE_FIELDS)
    assert _csv_header(out / "study_lambda.csv") == list(LAMBDA_FIELDS)
    assert [(r["method"], r["budget"]) for r in result.rows] == [
        ("current_state", 0),
        ("distance", 0),
        ("chance", 0),
        ("est", 3),
        ("montecarlo", 3),
    ]
    assert [(r["comparison"], r["budget"]) for r in result.differences] == [
        ("est - montecarlo", 3),
        ("est - distance", 3),
        ("est lambda 1 - lambda 5", 3),
    ]
    assert [r["lambda"] for r in result.lambdas] == [1.0, 5.0]
    for row in [*result.rows, *result.differences, *result.lambdas]:
        for question in QUESTION_NAMES:
            assert f"{question}_low" in row and f"{question}_high" in row
    # Chance AP is the positive rate of each capture question.
    dataset = load_dataset(out / "pushing" / "dataset")
    chance = result.rows[2]
    assert chance["capture_k0"] == pytest.approx(dataset.capture_labels(0).mean())
    # The task's own lambda (5) is the est-3 run itself: one tree per frame for both.
    est = result.rows[3]
    at_five = result.lambdas[1]
    assert all(at_five[q] == est[q] for q in QUESTION_NAMES)
    assert (out / "pushing" / "runs" / "est-3" / "scores.csv").is_file()
    assert (out / "pushing" / "study.csv").read_text() == (out / "study.csv").read_text()
    assert not (out / "pushing" / "lambda" / "est-3-lambda-5").exists()
    summary = json.loads((out / "study.json").read_text())
    assert summary["tasks"]["pushing"]["positive_rates"]["success"] == pytest.approx(dataset.success_labels().mean())
    assert len(summary["rows"]) == 5 and len(summary["lambdas"]) == 2
    assert sum(line.startswith("study [") for line in lines) == 2
    pytest.importorskip("matplotlib")
    assert (out / "study_pushing.png").stat().st_size > 0 and (out / "study_lambda_pushing.png").stat().st_size > 0


def test_an_interrupted_study_resumes_without_regrowing_a_tree(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    out = tmp_path / "study"
    frames = SMALL["n_trajectories"] * SMALL["n_frames"]
    # Interrupted at the 5th tree of the first configuration (the lambda sweep sharing est-3).
    first = CountingAnalyzeFrame(stop=5)
    monkeypatch.setattr(frame_module, "analyze_frame", first)
    with pytest.raises(KeyboardInterrupt):
        run_study(out, log=lambda line: None, **SMALL)
    # Resumed: the 5 missing frames of est-3 (scored at both lambdas), then montecarlo-3's 9.
    second = CountingAnalyzeFrame()
    monkeypatch.setattr(frame_module, "analyze_frame", second)
    resumed = run_study(out, log=lambda line: None, **SMALL)
    assert second.calls == (frames - 4) + frames
    # Finished: nothing is grown again and the tables are the same.
    third = CountingAnalyzeFrame()
    monkeypatch.setattr(frame_module, "analyze_frame", third)
    again = run_study(out, log=lambda line: None, **SMALL)
    assert third.calls == 0
    assert again.rows == resumed.rows and again.lambdas == resumed.lambdas and again.differences == resumed.differences


@pytest.fixture(scope="module")
def labelled(tmp_path_factory: pytest.TempPathFactory) -> Any:
    out = tmp_path_factory.mktemp("study") / "set"
    generate_dataset("pushing", n_objects=10, n_trajectories=24, n_frames=4, seed=0, out=out)
    dataset = load_dataset(out)
    assert 0.1 < dataset.capture_labels(0).mean() < 0.9
    return dataset


def test_paired_difference_of_identical_scores_is_exactly_zero(labelled: Any) -> None:
    questions = study_questions(labelled)
    rng = np.random.default_rng(0)
    resamples = rng.integers(0, labelled.n_trajectories, (200, labelled.n_trajectories))
    capture, success = rng.random((2, labelled.n_trajectories, labelled.n_frames))
    same = paired_difference(
        score_questions(questions, capture, success, resamples), score_questions(questions, capture, success, resamples)
    )
    for question in QUESTION_NAMES:
        assert same[question] == 0.0 and same[f"{question}_low"] == 0.0 and same[f"{question}_high"] == 0.0


def test_paired_difference_of_a_perfect_and_a_random_scorer_is_positive(labelled: Any) -> None:
    questions = study_questions(labelled)
    rng = np.random.default_rng(1)
    resamples = rng.integers(0, labelled.n_trajectories, (300, labelled.n_trajectories))
    labels = labelled.capture_labels(0).astype(float)
    noise = rng.random((labelled.n_trajectories, labelled.n_frames))
    perfect = score_questions(questions, labels, noise, resamples)
    random = score_questions(questions, noise, noise, resamples)
    difference = paired_difference(perfect, random)
    assert perfect.point["capture_k0"] == 1.0
    assert difference["capture_k0"] == pytest.approx(1.0 - random.point["capture_k0"])
    assert difference["capture_k0_low"] > 0.0
    # The interval is the percentile of the per-resample differences, resample by resample.
    expected = np.percentile(perfect.samples["capture_k0"] - random.samples["capture_k0"], [2.5, 97.5])
    assert (difference["capture_k0_low"], difference["capture_k0_high"]) == tuple(expected)
    # Same success scores on both sides: no success difference on any resample.
    assert difference["success_last3_low"] == difference["success_last3_high"] == 0.0


def test_lambda_rescoring_equals_a_direct_analysis_at_that_lambda(
    tiny_dataset: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    config = AnalyzerConfig(expansions=8)
    rescored = rescore_lambdas(tiny_dataset, tmp_path / "lambda", [0.5, 50.0], config=config, seed=4, progress=False)
    direct_dir = tmp_path / "direct"
    shutil.copytree(tiny_dataset, direct_dir)
    # The tree's own success score, as every lambda of a re-scoring scores it.
    analyze(direct_dir, AnalyzerConfig(expansions=8, likelihood_lambda=50.0, continuation=0), seed=4, progress=False)
    direct = load_scores(direct_dir)
    for column in ("capture_score", "success_score", "nodes", "expansions", "seed", "trajectory", "frame"):
        assert np.array_equal(rescored[50.0][column], direct[column]), column
    assert not np.array_equal(rescored[0.5]["capture_score"], rescored[50.0]["capture_score"])
    # The lambda directory is what analyze at that lambda writes: analyze finds it finished.
    counting = CountingAnalyzeFrame()
    monkeypatch.setattr(frame_module, "analyze_frame", counting)
    analyze(
        tmp_path / "lambda" / "est-8-lambda-50",
        AnalyzerConfig(expansions=8, likelihood_lambda=50.0, continuation=0),
        seed=4,
    )
    assert counting.calls == 0
    with pytest.raises(EnergyMarginError, match="converge"):
        rescore_lambdas(tiny_dataset, tmp_path / "x", [1.0], config=AnalyzerConfig(converge=0.01), progress=False)


def test_study_bad_input_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["study", str(tmp_path / "s"), "--trajectories", "1"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "trajectories" in err
    with pytest.raises(EnergyMarginError, match="expansions"):
        run_study(tmp_path / "s", **{**SMALL, "expansions": [3, 3]})
    old = {"trajectories": 3, "frames": 3, "budgets": [3], "lambda_budget": 3}
    renamed = {
        k: v for k, v in SMALL.items() if k not in {"n_trajectories", "n_frames", "expansions", "lambda_expansions"}
    }
    with (
        pytest.warns(DeprecationWarning, match="'budgets' is now 'expansions'"),
        pytest.raises(EnergyMarginError, match="expansions"),
    ):
        run_study(tmp_path / "s", **{**renamed, **old, "budgets": [3, 3]})


TRY_LOCK = """
import sys
from energy_margin.runs.lock import RunLock, RunLockedError
try:
    RunLock(sys.argv[1]).acquire()
except RunLockedError as error:
    print(error)
else:
    print("acquired")
"""


def _second_writer(directory: Path) -> str:
    """What a second process trying to lock ``directory`` gets (one line)."""
    return subprocess.run(
        [sys.executable, "-c", TRY_LOCK, str(directory)], capture_output=True, text=True, check=True
    ).stdout.strip()


def test_a_second_writer_is_refused_while_a_study_runs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "study"
    seen: list[str] = []

    def log(line: str) -> None:
        if not seen:  # the first line: the study has opened OUT and its task
            seen.append(_second_writer(out))

    run_study(out, log=log, **{**SMALL, "methods": ["est"], "lambdas": []})
    assert seen[0].startswith(f"{out} is being written by process {os.getpid()} ")
    assert "\n" not in seen[0]
    assert _second_writer(out) == "acquired"  # released at the end
    # A study started while another process holds OUT is refused in one line, writing nothing.
    holder = subprocess.Popen([sys.executable, "-c", HOLD, str(out)], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
        before = sorted(p.name for p in out.iterdir())
        code = main(["study", str(out), "--tasks", "pushing", "--trajectories", "3", "--frames", "3"])
        err = capsys.readouterr().err
        assert code == 2 and err.count("\n") == 1 and f"being written by process {holder.pid}" in err
        assert sorted(p.name for p in out.iterdir()) == before
    finally:
        holder.kill()
        holder.wait()


HOLD = """
import sys, time
from energy_margin.runs.lock import RunLock
lock = RunLock(sys.argv[1]).acquire()
print("held", flush=True)
time.sleep(60)
"""


def test_a_study_of_another_task_adds_to_out(tmp_path: Path) -> None:
    out = tmp_path / "study"
    quick = {**SMALL, "n_trajectories": 2, "n_frames": 2, "methods": ["est"], "lambdas": [], "bootstrap": 5}
    run_study(out, log=lambda line: None, **quick)
    specs = {**TINY_TASK, "scooping": StudyTask(objects=2, seed=3)}
    run_study(out, log=lambda line: None, **{**quick, "tasks": ["scooping"], "task_specs": specs})
    settings = json.loads((out / SETTINGS_FILE).read_text())
    assert sorted(settings["tasks"]) == ["pushing", "scooping"]
    assert (out / "pushing" / "study.csv").is_file() and (out / "scooping" / "study.csv").is_file()
    # A task studied before still decides: its entry changed is another study, refused.
    with pytest.raises(EnergyMarginError, match=r"tasks\.scooping\.seed: 2 there, 4 now"):
        run_study(out, log=lambda line: None, **{**quick, "tasks": ["scooping"], "task_specs": specs, "seed": 4})


def test_overwrite_replaces_a_study_of_another_seed(tmp_path: Path) -> None:
    out = tmp_path / "study"
    quick = {**SMALL, "methods": ["est"], "lambdas": []}
    first = run_study(out, log=lambda line: None, **quick)
    settings = json.loads((out / SETTINGS_FILE).read_text())
    assert settings["tasks"]["pushing"] == {"objects": 3, "dataset_seed": 3, "trajectories": 3, "frames": 3, "seed": 2}
    # Other budgets, methods or lambdas are the same study: it resumes.
    run_study(out, log=lambda line: None, **{**quick, "bootstrap": 10})
    with pytest.raises(
        EnergyMarginError, match=r"holds a study of other settings \(tasks\.pushing\.seed: 2 there, 4 now\)"
    ):
        run_study(out, log=lambda line: None, **{**quick, "seed": 4})
    assert json.loads((out / "study.json").read_text())["seed"] == 2  # refused before any output
    replaced = run_study(out, log=lambda line: None, overwrite=True, **{**quick, "seed": 4})
    assert json.loads((out / SETTINGS_FILE).read_text())["tasks"]["pushing"]["seed"] == 4
    assert json.loads((out / "study.json").read_text())["seed"] == 4
    analysis = json.loads((out / "pushing" / "runs" / "est-3" / "analysis.json").read_text())
    assert analysis["seed"] == 4
    assert [r["method"] for r in replaced.rows] == [r["method"] for r in first.rows]


def test_the_study_figures_are_displays_built_from_its_result(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    rows = [
        {"task": "pushing", "method": "distance", "budget": 0, **dict.fromkeys(_INTERVAL_KEYS, 0.5)},
        {"task": "pushing", "method": "est", "budget": 10, **dict.fromkeys(_INTERVAL_KEYS, 0.7)},
        {"task": "pushing", "method": "est", "budget": 30, **dict.fromkeys(_INTERVAL_KEYS, 0.8)},
    ]
    lambdas = [{"task": "pushing", "lambda": lam, **dict.fromkeys(_INTERVAL_KEYS, 0.6)} for lam in (0.0, 1.0, 10.0)]
    display = LambdaDisplay.from_result(lambdas, default=1.0, title="pushing")
    assert [r["lambda"] for r in display.rows] == [1.0, 10.0]  # no lambda 0 on the log axis
    budget = BudgetDisplay.from_result(rows, questions=QUESTION_NAMES, title="pushing")
    pytest.importorskip("matplotlib")
    assert len([a for a in budget.plot().figure_.axes if a.get_visible()]) == len(QUESTION_NAMES)
    assert len(display.plot().figure_.axes[0].get_lines()) == len(QUESTION_NAMES) + 1  # and the task's lambda
    result = StudyResult(rows, [], lambdas, {"trajectories": 3, "frames": 2, "tasks": {"pushing": _TASK_META}})
    (tmp_path / "pushing").mkdir()  # a study has made it
    written = draw_study(result, tmp_path)
    assert sorted(p.relative_to(tmp_path).as_posix() for p in written) == [
        "pushing/study_lambda_pushing.png",
        "pushing/study_pushing.png",
        "study_lambda_pushing.png",
        "study_pushing.png",
    ]
    monkeypatch.setattr(display_module, "pyplot", lambda: None)
    assert display.save(tmp_path / "x.png") is None and not (tmp_path / "x.png").exists()


_INTERVAL_KEYS = [f"{q}{s}" for q in QUESTION_NAMES for s in ("", "_low", "_high")]
_TASK_META = {"objects": 3, "likelihood_lambda": 1.0}
