"""Adaptive budgets: a frame's tree stops once both scores have converged (projected and window rules)."""

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
from energy_margin.errors import EnergyMarginError, InvalidParameterError
from energy_margin.planning.tree import CostField, TreeBudget


def _field(expansions: int, nodes: int | None = None) -> CostField:
    count = (expansions if nodes is None else nodes) + 1
    return CostField(
        costs=np.zeros(count),
        object_pos=np.zeros((count, 1, 3)),
        object_vel=np.zeros((count, 1, 6)),
        parents=np.full(count, -1),
        times=np.zeros(count),
        expansions=expansions,
        physics_s=0.0,
        total_s=0.0,
    )


def _rule(monkeypatch: pytest.MonkeyPatch, scores: list[tuple[float, float]], **kwargs: object) -> ScoresConverged:
    values = iter(scores)
    monkeypatch.setattr("energy_margin.analysis.convergence.score_field", lambda *args: next(values))
    return ScoresConverged(None, None, 1.0, **kwargs)  # type: ignore[arg-type]


def test_the_window_rule_waits_for_a_whole_window(monkeypatch: pytest.MonkeyPatch) -> None:
    rule = _rule(monkeypatch, [(0.5, 0.5)] * 10, tolerance=0.01, window=50, rule="window")
    assert rule(_field(25)) is False  # less than one window of history
    assert rule(_field(50)) is False  # checks at 25 and 50 span 25 expansions only
    assert rule(_field(75)) is True  # 25, 50, 75: unchanged over the last 50 expansions


def test_the_window_rule_needs_both_scores_still(monkeypatch: pytest.MonkeyPatch) -> None:
    moving = [(0.5, 0.1), (0.5, 0.2), (0.5, 0.3), (0.5, 0.3), (0.5, 0.3)]
    rule = _rule(monkeypatch, moving, tolerance=0.01, window=50, rule="window")
    decisions = [rule(_field(i)) for i in (25, 50, 75, 100, 125)]
    # Success still moves until expansion 75; from 75 to 125 it stays at 0.3.
    assert decisions == [False, False, False, False, True]


def test_the_window_rule_takes_the_spread_over_the_window(monkeypatch: pytest.MonkeyPatch) -> None:
    # A score that drifts by 0.006 per check moves 0.012 over two checks: more than 0.01.
    drifting = [(0.5 + 0.006 * i, 0.2) for i in range(8)]
    rule = _rule(monkeypatch, drifting, tolerance=0.01, window=50, rule="window")
    assert not any(rule(_field(25 * (i + 1))) for i in range(8))


def test_the_projected_rule_waits_for_a_whole_window(monkeypatch: pytest.MonkeyPatch) -> None:
    rule = _rule(monkeypatch, [(0.5, 0.5)] * 10, tolerance=0.01, window=50)
    assert rule.rule == "projected"
    assert rule(_field(25)) is False
    assert rule(_field(50)) is False  # no check 50 expansions back yet
    assert rule(_field(75)) is True  # unchanged since 25: nothing left to move


def test_the_projected_rule_lets_a_slow_drift_run_until_the_budget_cannot_carry_it(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # Capture falls by 0.002 per 25 expansions: 0.004 over a window, well inside 0.0105, so the
    # window rule stops at 75; at that rate the 300-expansion budget's rest would still move it
    # by (300 - n) / 50 * 0.004, which is <= 0.0105 from n = 175 on.
    drifting = [(0.9 - 0.002 * i, 0.0) for i in range(12)]
    checks = [25 * (i + 1) for i in range(12)]
    window = _rule(monkeypatch, drifting, tolerance=0.0105, window=50, rule="window")
    assert [window(_field(n)) for n in checks].index(True) == checks.index(75)
    projected = _rule(monkeypatch, drifting, tolerance=0.0105, window=50, budget=TreeBudget(expansions=300))
    assert [projected(_field(n)) for n in checks].index(True) == checks.index(175)


def test_the_projected_rule_counts_the_nodes_a_node_budget_still_allows(monkeypatch: pytest.MonkeyPatch) -> None:
    # 0.01 over the last 50 expansions; 100 nodes allowed, 95 accepted: 5 left, 0.001 to come.
    budget = TreeBudget(expansions=None, nodes=100)
    rule = _rule(monkeypatch, [(0.50, 0.2), (0.51, 0.2)], tolerance=0.002, window=50, budget=budget)
    assert rule(_field(50, nodes=45)) is False
    assert rule(_field(100, nodes=95)) is True


def test_the_reached_rule_does_not_stop_before_a_success_score_leaves_zero(monkeypatch: pytest.MonkeyPatch) -> None:
    flat = [(0.9, 0.0)] * 12
    checks = [25 * (i + 1) for i in range(12)]
    budget = TreeBudget(expansions=300)
    projected = _rule(monkeypatch, flat, tolerance=0.02, window=50, budget=budget)
    assert [projected(_field(n)) for n in checks].index(True) == checks.index(75)
    reached = _rule(monkeypatch, flat, tolerance=0.02, window=50, budget=budget, rule="projected-reached")
    assert not any(reached(_field(n)) for n in checks)


def test_the_reached_rule_is_the_projected_rule_once_success_has_left_zero(monkeypatch: pytest.MonkeyPatch) -> None:
    # Success leaves 0 at 100 expansions, then stays: settled once a window lies past the move.
    scores = [(0.9, 0.0 if n < 100 else 0.4) for n in range(25, 325, 25)]
    checks = list(range(25, 325, 25))
    budget = TreeBudget(expansions=300)
    reached = _rule(monkeypatch, scores, tolerance=0.02, window=50, budget=budget, rule="projected-reached")
    assert [reached(_field(n)) for n in checks].index(True) == checks.index(150)
    # Back at 0 does not undo it: the region was reached once, and the projected rule decides.
    again = [(0.9, 0.0), (0.9, 0.0), (0.9, 0.1), (0.9, 0.0)]
    rule = _rule(monkeypatch, again, tolerance=0.02, window=50, budget=budget, rule="projected-reached")
    assert [rule(_field(n)) for n in checks[:4]] == [False, False, False, True]


def test_the_rule_must_be_known() -> None:
    with pytest.raises(InvalidParameterError, match="rule must be one of projected, window"):
        ScoresConverged(None, None, 1.0, tolerance=0.01, window=50, rule="spread")  # type: ignore[arg-type]
    with pytest.raises(InvalidParameterError, match="converge_rule must be one of projected, window"):
        AnalyzerConfig(converge=0.01, converge_rule="spread")


@pytest.mark.parametrize("value", [0.0, 1.0, -0.1, float("nan"), True])
def test_converge_must_be_a_tolerance(value: object) -> None:
    with pytest.raises(InvalidParameterError, match="converge"):
        AnalyzerConfig(converge=value)  # type: ignore[arg-type]


def test_a_converged_tree_stops_early_and_deterministically(tiny_dataset: Path) -> None:
    dataset = load_dataset(tiny_dataset)
    seeds = frame_seeds(0, 6)
    config = AnalyzerConfig(expansions=400, converge=0.05)
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
        runs.append((scores.capture_score, scores.success_score, scores.expansions, field.nodes))
    assert runs[0] == runs[1]
    expansions = runs[0][2]
    assert config.converge_window <= expansions < 400
    assert expansions % config.converge_every == 0


def test_workers_do_not_change_converged_scores(copy_dataset) -> None:  # type: ignore[no-untyped-def]
    config = AnalyzerConfig(expansions=200, converge=0.02)
    tables = []
    for workers in (1, 2):
        directory = copy_dataset(f"w{workers}")
        analyze(directory, config, seed=4, workers=workers, progress=False)
        scores = load_scores(directory)
        tables.append({k: scores[k].tolist() for k in ("capture_score", "success_score", "expansions", "seed")})
    assert tables[0] == tables[1]
    assert max(tables[0]["expansions"]) <= 200


def test_cli_converge_is_recorded(tiny_dataset: Path) -> None:
    assert main(["analyze", str(tiny_dataset), "--expansions", "100", "--converge", "0.05", "--no-progress"]) == 0
    recorded = json.loads((tiny_dataset / CONFIG_FILE).read_text())
    assert recorded["analyzer"]["converge"] == 0.05
    assert max(load_scores(tiny_dataset)["expansions"]) <= 100


def test_cli_converge_rule_is_recorded(tiny_dataset: Path) -> None:
    arguments = ["analyze", str(tiny_dataset), "--expansions", "100", "--converge", "0.05", "--no-progress"]
    assert main([*arguments, "--converge-rule", "window"]) == 0
    recorded = json.loads((tiny_dataset / CONFIG_FILE).read_text())
    assert recorded["analyzer"]["converge_rule"] == "window"


def test_a_file_from_before_the_rule_existed_resumes_only_under_the_window_rule(tiny_dataset: Path) -> None:
    config = AnalyzerConfig(expansions=60, converge=0.05, converge_rule="window")
    analyze(tiny_dataset, config, seed=0, progress=False)
    path = tiny_dataset / CONFIG_FILE
    recorded = json.loads(path.read_text())
    del recorded["analyzer"]["converge_rule"]  # as written before the setting existed
    path.write_text(json.dumps(recorded))
    analyze(tiny_dataset, config, seed=0, progress=False)  # the same run: nothing to redo
    with pytest.raises(EnergyMarginError, match="holds scores of other settings"):
        analyze(tiny_dataset, AnalyzerConfig(expansions=60, converge=0.05), seed=0, progress=False)


def test_a_full_budget_file_from_before_the_rule_existed_still_resumes(tiny_dataset: Path) -> None:
    config = AnalyzerConfig(expansions=20)
    analyze(tiny_dataset, config, seed=0, progress=False)
    path = tiny_dataset / CONFIG_FILE
    recorded = json.loads(path.read_text())
    del recorded["analyzer"]["converge_rule"]
    path.write_text(json.dumps(recorded))
    analyze(tiny_dataset, config, seed=0, progress=False)  # no tolerance: the rule never mattered


def test_cli_spends_the_whole_budget_by_default(tiny_dataset: Path) -> None:
    assert main(["analyze", str(tiny_dataset), "--expansions", "40", "--no-progress"]) == 0
    recorded = json.loads((tiny_dataset / CONFIG_FILE).read_text())
    assert recorded["analyzer"]["converge"] is None
    assert set(load_scores(tiny_dataset)["expansions"]) == {40}
