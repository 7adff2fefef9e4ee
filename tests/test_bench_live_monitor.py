"""benchmarks/live_monitor.py: a live dataset's scores are the wrapper's calls, and calibrate alike."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench_modules import load_benchmark
from energy_margin.evaluation.live_calibration import calibrate_episodes
from energy_margin.evaluation.monitor import calibrate_grid


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("live_monitor")


def test_a_scores_file_s_rows_are_each_episode_s_calls_in_frame_order(bench) -> None:
    # Rows out of order, as a journal may hold them; the second episode's tree capture unknown (NaN).
    scores = {
        "trajectory": np.array([1, 0, 1, 0]),
        "frame": np.array([1, 1, 0, 0]),
        "capture_score": np.array([0.4, 0.3, 0.2, 0.1]),
        "success_score": np.array([0.8, 0.7, 0.6, 0.5]),
        "tree_capture_score": np.array([math.nan, 0.9, math.nan, 0.95]),
    }
    episodes = bench.episodes_of(scores)
    assert [[call["success_score"] for call in calls] for calls in episodes] == [[0.5, 0.7], [0.6, 0.8]]
    assert episodes[0][0]["tree_capture_score"] == 0.95 and math.isnan(episodes[1][1]["tree_capture_score"])


def test_calibrating_on_the_calls_is_calibrating_on_the_grid(bench) -> None:
    """What the benchmark checks on the measured runs: the live calibration equals the grid's."""
    rng = np.random.default_rng(0)
    success = rng.random((30, 11))
    scores = {
        "trajectory": np.repeat(np.arange(30), 11),
        "frame": np.tile(np.arange(11), 30),
        "capture_score": np.ones(330),
        "success_score": success.reshape(-1),
        "tree_capture_score": np.ones(330),
    }
    labels = rng.random(30) < 0.8
    for persistence in (1, 2):
        grid = calibrate_grid(success, labels, alpha=0.1, start_frame=2, persistence=persistence)
        live = calibrate_episodes(bench.episodes_of(scores), labels, alpha=0.1, start_frame=2, persistence=persistence)
        assert (live.threshold, live.rank, live.n_successes) == (grid.threshold, grid.rank, grid.n_successes)


def test_a_reused_run_keeps_the_load_average_it_was_scored_under(bench, tmp_path) -> None:
    dataset = tmp_path / "calibration" / "dataset"
    dataset.mkdir(parents=True)
    assert bench._load_average(dataset) is None
    (dataset.parent / bench.LOAD_FILE).write_text('{"load_average": 1.5}\n')
    assert bench._load_average(dataset) == 1.5
