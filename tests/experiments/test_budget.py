from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from sklearn.metrics import average_precision_score

from energy_margin.cli import main
from energy_margin.errors import EnergyMarginError
from energy_margin.experiments.budget import (
    QUESTION_LABELS,
    QUESTIONS,
    SETTINGS_FILE,
    BudgetSweepResult,
    average_precision,
    budget_sweep,
    plot,
)
from energy_margin.experiments.budget_display import BudgetDisplay
from energy_margin.runs.tables import write_json


@pytest.mark.parametrize("seed", range(5))
def test_average_precision_matches_scikit_learn(seed: int) -> None:
    rng = np.random.default_rng(seed)
    labels = rng.random(60) < 0.4
    scores = np.round(rng.random(60), 1)  # ties
    assert average_precision(labels, scores) == pytest.approx(average_precision_score(labels, scores))
    assert average_precision(np.ones(4, bool), np.arange(4.0)) is None


@pytest.mark.slow
def test_budget_sweep_writes_tables_and_resumes(tiny_dataset: Path, capsys: pytest.CaptureFixture[str]) -> None:
    before = sorted(p.name for p in tiny_dataset.iterdir())
    code = main(["budget", str(tiny_dataset), "--expansions", "5", "10", "--bootstrap", "50", "--seed", "3"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert "montecarlo" in captured.out and "rrt" in captured.out
    work = tiny_dataset / "budget"
    assert (work / "budget.csv").is_file() and (work / "budget.json").is_file()
    assert not (tiny_dataset / "scores.csv").exists()  # the dataset's own scores are untouched
    assert sorted(p.name for p in tiny_dataset.iterdir()) == sorted([*before, "budget"])
    summary = json.loads((work / "budget.json").read_text())
    rows = summary["rows"]
    assert {(r["method"], r["budget"]) for r in rows} >= {(m, b) for m in ("est", "montecarlo", "rrt") for b in (5, 10)}
    assert {"current_state", "distance"} <= {r["method"] for r in rows}
    for row in rows:
        for question in ("capture_ap", "capture_ap_window2", "success_ap_first_half"):
            value, low, high = row[question], row[f"{question}_low"], row[f"{question}_high"]
            if value is not None and low is not None:
                assert low - 1e-12 <= value <= high + 1e-12
    est = next(r for r in rows if r["method"] == "est" and r["budget"] == 10)
    assert est["frames"] == 6 and est["runtime_per_frame_s"] > 0
    lines = (work / "budget.csv").read_text().splitlines()
    assert lines[0].startswith("method,budget,capture_ap,capture_ap_low")
    assert len(lines) == len(rows) + 1
    # A second run finds every analysis finished and gives the same rows.
    again = budget_sweep(tiny_dataset, expansions=[5, 10], bootstrap=50, seed=3, log=lambda line: None)
    assert [r["capture_ap"] for r in again.rows] == [r["capture_ap"] for r in rows]


def test_the_sweep_is_typed_and_its_dictionary_is_the_json(tiny_dataset: Path, tmp_path: Path) -> None:
    import warnings

    result = budget_sweep(tiny_dataset, expansions=[3], methods=["est"], bootstrap=5, seed=2, log=lambda line: None)
    assert isinstance(result, BudgetSweepResult)
    assert result.dataset == str(tiny_dataset) and result.seed == 2 and result.bootstrap == 5 and result.workers == 1
    assert [(row["method"], row["budget"]) for row in result.rows][-1] == ("est", 3)
    # The JSON written is the dictionary of the dataset, the settings and the rows, as before.
    written = tiny_dataset / "budget" / "budget.json"
    earlier = {
        "dataset": str(tiny_dataset),
        "task": result.task,
        "n_trajectories": result.n_trajectories,
        "n_frames": result.n_frames,
        "n_objects": result.n_objects,
        "seed": 2,
        "bootstrap": 5,
        "workers": 1,
        "analyzer": result.analyzer,
        "title": result.title,
        "rows": result.rows,
    }
    assert result.to_dict() == json.loads(written.read_text()) == json.loads(json.dumps(earlier))
    write_json(tmp_path / "typed.json", result.to_dict())
    write_json(tmp_path / "earlier.json", earlier)
    assert written.read_bytes() == (tmp_path / "typed.json").read_bytes() == (tmp_path / "earlier.json").read_bytes()
    # Reading it as the dictionary, or as the list of rows, of earlier releases still works, with a warning.
    with pytest.warns(DeprecationWarning, match=r"use \.seed"):
        assert result["seed"] == 2
    with pytest.warns(DeprecationWarning, match=r"use \.rows\[-1\]"):
        assert result[-1] == result.rows[-1]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert "rows" in result and list(result) == list(earlier)


def test_budget_bad_input_is_one_line(tiny_dataset: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["budget", str(tmp_path / "missing"), "--expansions", "5"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "error" in err
    with pytest.raises(SystemExit) as exit_:
        main(["budget", str(tiny_dataset), "--expansions", "0"])
    code = exit_.value.code
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    with pytest.raises(EnergyMarginError, match="methods"):
        budget_sweep(tiny_dataset, methods=["prm"])


def test_budget_overwrite_replaces_only_the_sweep(tiny_dataset: Path) -> None:
    work = tiny_dataset / "budget"
    quick = {"expansions": [3], "methods": ["est"], "bootstrap": 5, "log": lambda line: None}
    budget_sweep(tiny_dataset, seed=0, **quick)
    assert json.loads((work / SETTINGS_FILE).read_text())["seed"] == 0
    (work / "notes.txt").write_text("mine")
    budget_sweep(tiny_dataset, seed=0, **{**quick, "expansions": [2], "bootstrap": 3})  # the same sweep: resumes
    assert (work / "est-2").is_dir() and (work / "est-3").is_dir()
    with pytest.raises(EnergyMarginError, match=r"holds a budget sweep of other settings \(seed: 0 there, 1 now\)"):
        budget_sweep(tiny_dataset, seed=1, **quick)
    budget_sweep(tiny_dataset, seed=1, overwrite=True, **quick)
    assert json.loads((work / SETTINGS_FILE).read_text())["seed"] == 1
    assert json.loads((work / "est-3" / "analysis.json").read_text())["seed"] == 1
    assert not (work / "est-2").exists()  # the earlier sweep's analyses went
    assert (work / "notes.txt").read_text() == "mine"  # a file of no sweep stays


def test_a_second_writer_is_refused_while_a_sweep_runs(tiny_dataset: Path) -> None:
    seen: list[str] = []
    script = "import sys\nfrom energy_margin.runs.lock import RunLock\nRunLock(sys.argv[1]).acquire()\n"

    def log(line: str) -> None:
        other = subprocess.run(
            [sys.executable, "-c", script, str(tiny_dataset / "budget")], capture_output=True, text=True
        )
        seen.append(other.stderr.strip().splitlines()[-1])

    budget_sweep(tiny_dataset, expansions=[3], methods=["est"], bootstrap=5, log=log)
    assert "RunLockedError" in seen[0] and f"is being written by process {os.getpid()}" in seen[0]


def test_the_budget_figure_is_a_display_built_from_the_rows(tmp_path: Path) -> None:
    rows = [
        {"method": "current_state", "budget": 0, "capture_ap": 0.5, "capture_ap_window2": 0.4},
        {
            "method": "est",
            "budget": 10,
            "capture_ap": 0.8,
            "capture_ap_low": 0.7,
            "capture_ap_high": 0.9,
            "success_ap_first_half": 0.6,
            "success_ap_first_half_low": None,
            "success_ap_first_half_high": None,
        },
        {"method": "est", "budget": 30, "capture_ap": 0.9, "capture_ap_low": 0.8, "capture_ap_high": 1.0},
    ]
    display = BudgetDisplay.from_result(rows, questions=QUESTIONS, labels=QUESTION_LABELS, title="tiny")
    assert display.rows == rows and display.rows is not rows
    pytest.importorskip("matplotlib")
    figure = display.plot().figure_
    assert [axis.get_title() for axis in figure.axes] == [QUESTION_LABELS[q] for q in QUESTIONS]
    assert plot(rows, tmp_path / "budget.png", title="tiny") == tmp_path / "budget.png"
    assert (tmp_path / "budget.png").stat().st_size > 0
