"""The trees' rejected and diverged states: summarised per frame, and said in one line when frequent."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.run import analyze
from energy_margin.cli import main
from energy_margin.data.scores_file import load_scores, rejection_note, tree_rejections


def _scores(rejected: list[int], diverged: list[int], expansions: int = 100) -> dict[str, np.ndarray]:
    return {
        "rejected": np.array(rejected),
        "diverged": np.array(diverged),
        "expansions": np.full(len(rejected), expansions),
    }


def test_the_counts_are_summarised_per_frame_and_as_shares() -> None:
    summary = tree_rejections(_scores([10, 30], [0, 2]))
    assert summary == pytest.approx(
        {"rejected_per_frame": 20.0, "diverged_per_frame": 1.0, "rejected_share": 0.2, "diverged_share": 0.01}
    )
    assert rejection_note(_scores([10, 30], [0, 2])) is None  # 1 % diverged is not "often"


def test_frequent_divergence_and_rejection_are_said_in_one_line() -> None:
    diverged = rejection_note(_scores([0, 0], [5, 5]))
    assert diverged is not None and "5.0% of the trees' expansions diverged" in diverged
    assert "wrenches may be too large for light objects" in diverged and "\n" not in diverged
    rejected = rejection_note(_scores([40, 60], [0, 0]))
    assert rejected is not None and "50.0% of the trees' expansions left the state box" in rejected


def test_unknown_counts_give_no_summary() -> None:
    assert tree_rejections(_scores([-1, -1], [-1, -1])) is None
    assert rejection_note(_scores([-1, -1], [-1, -1])) is None


def test_evaluate_shows_the_counts(tiny_dataset: Path, capsys: pytest.CaptureFixture[str]) -> None:
    analyze(tiny_dataset, AnalyzerConfig(expansions=30), seed=0, progress=False)
    scores = load_scores(tiny_dataset)
    capsys.readouterr()
    assert main(["evaluate", str(tiny_dataset)]) == 0
    out = capsys.readouterr().out
    expected = tree_rejections(scores)
    assert expected is not None
    assert f"tree states rejected per frame: {expected['rejected_per_frame']:.1f} outside the state box" in out
