"""Adaptive budgets: a frame's tree stops once both scores have converged."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from energy_margin.analysis.frame import AnalyzerConfig, ScoresConverged, analyze_frame, frame_seeds
from energy_margin.analysis.run import analyze
from energy_margin.cli import main
from energy_margin.data.dataset import load_dataset
from energy_margin.data.scores_file import CONFIG_FILE, load_scores
from energy_margin.planning.tree import CostField


def _field(iterations: int) -> CostField:
    return CostField(
        costs=np.zeros(iterations + 1),
        object_pos=np.zeros((iterations + 1, 1, 3)),
        object_vel=np.zeros((iterations + 1, 1, 6)),
        parents=np.full(iterations + 1, -1),
        times=np.zeros(iterations + 1),
        iterations=iterations,
        physics_s=0.0,
        total_s=0.0,
    )


def _rule(monkeypatch: pytest.MonkeyPatch, scores: list[tuple[float, float]], **kwargs: object) -> ScoresConverged:
    values = iter(scores)
    monkeypatch.setattr("energy_margin.analysis.frame.score_field", lambda *args: next(values))
    return ScoresConverged(None, None, 1.0, **kwargs)  # type: ignore[arg-type]


def test_the_rule_waits_for_a_whole_window(monkeypatch: pytest.MonkeyPatch) -> None:
    rule = _rule(monkeypatch, [(0.5, 0.5)] * 10, tolerance=0.01, window=50)
    assert rule(_field(25)) is False  # less than one window of history
    assert rule(_field(50)) is False  # checks at 25 and 50 span 25 expansions only
    assert rule(_field(75)) is True  # 25, 50, 75: unchanged over the last 50 expansions


def test_the_rule_needs_both_scores_still(monkeypatch: pytest.MonkeyPatch) -> None:
    moving = [(0.5, 0.1), (0.5, 0.2), (0.5, 0.3), (0.5, 0.3), (0.5, 0.3)]
    rule = _rule(monkeypatch, moving, tolerance=0.01, window=50)
    decisions = [rule(_field(i)) for i in (25, 50, 75, 100, 125)]
    # Success still moves until expansion 75; from 75 to 125 it stays at 0.3.
    assert decisions == [False, False, False, False, True]


def test_the_rule_takes_the_spread_over_the_window(monkeypatch: pytest.MonkeyPatch) -> None:
    # A score that drifts by 0.006 per check moves 0.012 over two checks: more than 0.01.
    drifting = [(0.5 + 0.006 * i, 0.2) for i in range(8)]
    rule = _rule(monkeypatch, drifting, tolerance=0.01, window=50)
    assert not any(rule(_field(25 * (i + 1))) for i in range(8))


@pytest.mark.parametrize("value", [0.0, 1.0, -0.1, float("nan"), True])
def test_converge_must_be_a_tolerance(value: object) -> None:
    with pytest.raises(ValueError, match="converge"):
        AnalyzerConfig(converge=value)  # type: ignore[arg-type]


def test_a_converged_tree_stops_early_and_deterministically(tiny_dataset: Path) -> None:
    dataset = load_dataset(tiny_dataset)
    seeds = frame_seeds(0, 6)
    config = AnalyzerConfig(iterations=400, converge=0.05)
    runs = []
    for _ in range(2):
        scores, field = analyze_frame(
            dataset.task,
            dataset.frame(0, 1),
            friction=float(dataset.arrays["friction"][0]),
            drive=dataset.arrays["drive"][0],
            seed=seeds[1],
            config=config,
            start_time=float(dataset.arrays["frame_time"][0, 1]),
        )
        runs.append((scores.capture_score, scores.success_score, scores.iterations, field.nodes))
    assert runs[0] == runs[1]
    iterations = runs[0][2]
    assert config.converge_window <= iterations < 400
    assert iterations % config.converge_every == 0


def test_workers_do_not_change_converged_scores(copy_dataset) -> None:  # type: ignore[no-untyped-def]
    config = AnalyzerConfig(iterations=200, converge=0.02)
    tables = []
    for workers in (1, 2):
        directory = copy_dataset(f"w{workers}")
        analyze(directory, config, seed=4, workers=workers, progress=False)
        scores = load_scores(directory)
        tables.append({k: scores[k].tolist() for k in ("capture_score", "success_score", "iterations", "seed")})
    assert tables[0] == tables[1]
    assert max(tables[0]["iterations"]) <= 200


def test_cli_converge_is_recorded(tiny_dataset: Path) -> None:
    assert main(["analyze", str(tiny_dataset), "--iterations", "100", "--converge", "0.05", "--no-progress"]) == 0
    recorded = json.loads((tiny_dataset / CONFIG_FILE).read_text())
    assert recorded["analyzer"]["converge"] == 0.05
    assert max(load_scores(tiny_dataset)["iterations"]) <= 100
