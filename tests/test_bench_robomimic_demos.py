"""benchmarks/robomimic_demos.py: its answers are evaluate's, on a tiny scene set."""

from __future__ import annotations

from pathlib import Path

import pytest

from bench_modules import load_benchmark
from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.run import analyze
from energy_margin.data.generate import generate_dataset
from energy_margin.evaluation.metrics import evaluate
from tiny_scene import write_tiny_scene


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("robomimic_demos")


def test_a_sets_answers_are_evaluates(bench, tmp_path: Path) -> None:
    scene = write_tiny_scene(tmp_path / "scene")
    directory = tmp_path / "set"
    generate_dataset("scene", n_objects=2, n_trajectories=6, n_frames=6, seed=0, out=directory,
                     task_config={"scene_file": str(scene)})  # fmt: skip
    analyze(directory, AnalyzerConfig(expansions=10, continuation=0), seed=0, progress=False)
    found = bench.set_results(directory, resamples=20)
    assert found["robot"] == "declared" and (found["trajectories"], found["frames"]) == (6, 6)
    answers = found["questions"]
    assert len(answers) == 6 and list(answers)[-1] == bench.LAST_3
    for window, question in zip((0, 2, 4), list(answers)[:3], strict=True):
        direct = evaluate(directory, capture_window=window, resamples=0)
        assert answers[question]["margin"] == pytest.approx(direct.capture_ap, abs=1e-12)
    last = evaluate(directory, resamples=0).success_ap  # the last 3 frames, linear weights
    assert answers[bench.LAST_3]["margin"] == pytest.approx(last, abs=1e-12)
    for row in answers.values():
        assert 0 <= row["verdict"]["resamples"] <= 20
        assert row["cell"] == "n/a" if row["margin"] is None else row["cell"].startswith(f"{row['margin']:.3f}")
    assert set(found["baselines"]) >= {"current_state"}
    rows = bench.table_rows({"tiny": found})
    assert [row["question"] for row in rows] == list(answers)
    assert rows[0]["margin"] == answers[rows[0]["question"]]["cell"] and rows[0]["set"] == "tiny"
    assert rows[0]["current_state"] == f"{found['baselines']['current_state'][rows[0]['question']]:.3f}"


def test_a_sets_analysis_time_is_kept_beside_its_scores(bench, tmp_path: Path, monkeypatch) -> None:
    """A resumed benchmark reports the time its first run measured; a set analysed without it reports none."""
    scene = write_tiny_scene(tmp_path / "scene")
    directory = tmp_path / "set"
    generate_dataset("scene", n_objects=2, n_trajectories=2, n_frames=2, seed=0, out=directory,
                     task_config={"scene_file": str(scene)})  # fmt: skip
    calls = []

    def fake_cli(*argv) -> None:
        calls.append(argv)
        analyze(directory, AnalyzerConfig(expansions=5, continuation=0), seed=0, progress=False)

    monkeypatch.setattr(bench, "_cli", fake_cli)
    seconds = bench._analysed(directory)
    assert len(calls) == 1 and calls[0][0] == "analyze" and seconds is not None and seconds > 0
    assert bench._analysed(directory) == seconds and len(calls) == 1
    (directory / bench.SECONDS_FILE).unlink()
    assert bench._analysed(directory) is None and len(calls) == 1
