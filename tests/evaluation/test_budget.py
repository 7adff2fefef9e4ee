from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from sklearn.metrics import average_precision_score

from energy_margin.cli import main
from energy_margin.errors import EnergyMarginError
from energy_margin.evaluation.budget import average_precision, budget_sweep


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
    code = main(["budget", str(tiny_dataset), "--budgets", "5", "10", "--bootstrap", "50", "--seed", "3"])
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
    again = budget_sweep(tiny_dataset, budgets=[5, 10], bootstrap=50, seed=3, log=lambda line: None)
    assert [r["capture_ap"] for r in again] == [r["capture_ap"] for r in rows]


def test_budget_bad_input_is_one_line(tiny_dataset: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["budget", str(tmp_path / "missing"), "--budgets", "5"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "error" in err
    with pytest.raises(SystemExit) as exit_:
        main(["budget", str(tiny_dataset), "--budgets", "0"])
    code = exit_.value.code
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    with pytest.raises(EnergyMarginError, match="methods"):
        budget_sweep(tiny_dataset, methods=["prm"])
