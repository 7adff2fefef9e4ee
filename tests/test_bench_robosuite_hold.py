"""benchmarks/robosuite_hold.py: one hold's entry from the example's results and its evaluate text."""

from __future__ import annotations

import pytest

from bench_modules import load_benchmark

KEYS = ("capture_ap", "capture_ap_window2", "success_ap", "success_ap_first_half")


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("robosuite_hold")


def _evaluation(margin: float, best: float, word: str) -> dict:
    verdict = {"baseline": "distance", "difference": margin - best, "low": -0.1, "high": 0.2, "word": word}
    return {
        **dict.fromkeys(KEYS, margin),
        "baselines": {"distance": dict.fromkeys(KEYS, best), "chance": dict.fromkeys(KEYS, 0.4)},
        "verdict": dict.fromkeys(KEYS, verdict),
    }


def test_an_entry_keeps_both_evaluations_the_live_calls_and_the_analysis_time(bench) -> None:
    results = {
        "mujoco": "3.9.0",
        "robosuite": "1.5.2",
        "episodes": [{}] * 40,
        "success_rate": 0.375,
        "timing": {"mean_ms": 46.5, "mean_expansions": 9.8},
        "evaluate": {"analyze": _evaluation(0.635, 0.375, "ahead"), "live": _evaluation(0.458, 0.375, "level")},
    }
    entry = bench.summary(results, 4.215)
    assert (entry["episodes"], entry["success_rate"], entry["seconds_per_frame"]) == (40, 0.375, 4.215)
    assert (entry["live_mean_ms"], entry["live_mean_expansions"]) == (46.5, 9.8)
    early = entry["analyze"]["success_ap_first_half"]
    assert (early["margin"], early["baseline"], early["baseline_ap"], early["word"]) == (
        0.635,
        "distance",
        0.375,
        "ahead",
    )
    assert entry["live"]["success_ap_first_half"]["margin"] == 0.458
    assert entry["live"]["success_ap_first_half"]["word"] == "level"
    assert bench.summary(results, None)["seconds_per_frame"] is None


def test_the_analysis_time_is_evaluates(bench, tmp_path) -> None:
    from energy_margin.analysis.frame import AnalyzerConfig
    from energy_margin.analysis.run import analyze
    from energy_margin.data.generate import generate_dataset
    from energy_margin.evaluation.metrics import evaluate
    from tiny_scene import write_tiny_scene

    scene = write_tiny_scene(tmp_path / "scene")
    dataset = tmp_path / "run" / "dataset"
    generate_dataset("scene", n_objects=2, n_trajectories=2, n_frames=4, seed=0, out=dataset,
                     task_config={"scene_file": str(scene)})  # fmt: skip
    analyze(dataset, AnalyzerConfig(expansions=5, continuation=0), seed=0, progress=False)
    expected = evaluate(dataset, resamples=0).to_dict()["runtime_per_frame_s"]
    assert bench.seconds_per_frame(tmp_path / "run") == pytest.approx(expected, rel=1e-12)


def test_the_recorded_entry_s_scene_is_the_coasting_scene_following_the_paths(bench) -> None:
    coasting = (
        "[objects]\n\n# The controller's torques are not known ahead: the robot keeps each frame's joint velocities.\n"
        '[motion]\nduration = 9.0\nrobot = "coasting"\n'
    )
    recorded = bench.recorded_scene(coasting)
    assert 'robot = "recorded"\n' in recorded and 'robot = "coasting"' not in recorded
    assert (
        "# The controller's torques are not known ahead: the robot follows each episode's recorded joint path.\n"
        in (recorded)
    )
    assert recorded.count("\n") == coasting.count("\n")
    with pytest.raises(ValueError, match="has no line"):
        bench.recorded_scene(coasting.replace('robot = "coasting"', 'robot = "still"'))
