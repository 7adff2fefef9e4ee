"""``progress`` is one concept: True a bar on standard error, a callable gets counts, False or None nothing."""

from __future__ import annotations

from pathlib import Path

import pytest

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.run import analyze
from energy_margin.data.generate import generate_dataset
from energy_margin.runs.progress import progress_bar


def test_a_callable_receives_every_update_and_false_prints_nothing(capsys: pytest.CaptureFixture[str]) -> None:
    counts: list[int] = []
    bar = progress_bar(5, desc="x", enabled=counts.append)
    bar.update(2)
    bar.update()
    bar.close()
    assert counts == [2, 1]
    for quiet in (False, None):
        progress_bar(5, desc="x", enabled=quiet).update(1)
    assert capsys.readouterr().err == ""


def test_generate_and_analyze_take_either_form(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    trajectories: list[int] = []
    dataset = generate_dataset(
        "pushing", n_objects=2, n_trajectories=2, n_frames=2, seed=0, out=tmp_path / "d", progress=trajectories.append
    )
    assert trajectories == [1, 1]
    frames: list[int] = []
    analyze(tmp_path / "d", AnalyzerConfig(expansions=3), seed=0, progress=frames.append)
    assert sum(frames) == dataset.n_trajectories * dataset.n_frames == 4
    assert "analyze" not in capsys.readouterr().err
    generate_dataset("pushing", n_objects=2, n_trajectories=2, n_frames=2, seed=1, out=tmp_path / "e", progress=True)
    assert "generate" in capsys.readouterr().err
