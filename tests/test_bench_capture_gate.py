"""benchmarks/capture_gate.py: its gated column is what analyze writes with the gate."""

from __future__ import annotations

from pathlib import Path

import pytest

from bench_modules import load_benchmark
from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.run import analyze
from energy_margin.data.dataset import load_dataset
from energy_margin.data.generate import generate_dataset
from energy_margin.evaluation.metrics import evaluate


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("capture_gate")


def test_gated_rows_are_what_analyze_writes_with_the_gate(bench, tmp_path: Path) -> None:
    # Four objects, seed 3: some of the twelve frames start with an object outside the capture region.
    paper, gated = tmp_path / "paper", tmp_path / "gated"
    for directory in (paper, gated):
        generate_dataset("pushing", out=directory, n_objects=4, n_trajectories=3, n_frames=4, seed=3)
    analyze(paper, AnalyzerConfig(expansions=40, capture_gate="none", continuation=0), seed=2, progress=False)
    analyze(gated, AnalyzerConfig(expansions=40, continuation=0), seed=2, progress=False)
    found = bench.gated_rows(paper)
    assert found["changed_frames"] >= 1
    captured = load_dataset(paper).arrays["captured"]
    assert found["uncaptured_share"] == pytest.approx(1.0 - captured.mean())
    for window in (0, 2):
        direct_paper = evaluate(paper, capture_window=window, resamples=0).capture_ap
        direct_gated = evaluate(gated, capture_window=window, resamples=0).capture_ap
        assert found[f"capture_k{window}"]["none"]["ap"] == pytest.approx(direct_paper, abs=1e-12)
        assert found[f"capture_k{window}"]["current"]["ap"] == pytest.approx(direct_gated, abs=1e-12)
    # Gated, capture now ranks every captured frame above every frame that is not: the label's own AP.
    assert found["capture_k0"]["current"]["ap"] == pytest.approx(1.0)
    assert found["capture_k0"]["current"]["ap"] >= found["capture_k0"]["none"]["ap"]
    # Early success is the same both ways: the gate does not touch the success score.
    assert found["success_first3"]["none"] == found["success_first3"]["current"]
    assert found["success_first5"]["none"] == found["success_first5"]["current"]
    assert set(found["capture_k2"]["baselines"]) >= {"current_state", "distance"}


def test_every_scene_names_where_its_set_comes_from(bench) -> None:
    for spec in bench.SCENES.values():
        assert len({"scene", "record", "task"} & set(spec)) == 1
        if "scene" in spec:
            assert (bench.EXAMPLES / spec["scene"] / f"{spec['scene']}.toml").is_file()
