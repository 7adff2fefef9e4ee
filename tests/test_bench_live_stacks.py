"""benchmarks/bench_live_stacks.py: its variants, as before and now, on the Pusher."""

from __future__ import annotations

import argparse

import numpy as np
import pytest

from bench_modules import load_benchmark
from energy_margin.analysis.live import score_state
from energy_margin.planning.nodes import _Tree
from energy_margin.tasks import get_task


def test_costing_at_every_check_reads_the_field_and_keeps_the_scores(monkeypatch: pytest.MonkeyPatch) -> None:
    bench = load_benchmark("bench_live_stacks")
    task = get_task("pushing")
    trajectory = task.sample_trajectory(np.random.default_rng(2), 3)
    views: list[int] = []
    view = _Tree.view

    def counted_view(nodes, expansions):
        views.append(expansions)
        return view(nodes, expansions)

    monkeypatch.setattr(_Tree, "view", counted_view)
    options = {"friction": trajectory.friction, "drive": trajectory.drive, "budget_s": 60.0, "max_expansions": 15}
    now = score_state(task, trajectory.initial, seed=3, **options)
    assert views == []
    with bench.costing_at_every_check(True):
        before = score_state(task, trajectory.initial, seed=3, **options)
    assert views == list(range(1, 16))
    with bench.costing_at_every_check(False):
        score_state(task, trajectory.initial, seed=3, **options)
    assert len(views) == 15  # off: no field read, and the patch is undone on leaving
    assert (now.capture, now.success, now.nodes) == (before.capture, before.success, before.nodes)


def test_every_variant_scores_the_pusher(tmp_path) -> None:
    pytest.importorskip("gymnasium")
    bench = load_benchmark("bench_live_stacks")
    args = argparse.Namespace(stack="pusher", steps=2, budget=0.01, seed=0)
    rows = bench.measure(args, tmp_path)["rows"]
    assert [row["variant"] for row in rows] == list(bench.VARIANTS)
    assert all(row["expansions_min"] >= 1 and row["ms_median"] > 0.0 for row in rows)


def test_one_region_per_state_builds_no_stacked_region(tmp_path) -> None:
    from energy_margin.tasks.region_types import FrameRegions

    bench = load_benchmark("bench_live_stacks")
    scene = tmp_path / "scene.toml"
    model = tmp_path / "model.xml"
    model.write_text(
        "<mujoco><worldbody><body name='arm'><joint name='slide' type='slide'/><geom size='.05'/></body>"
        "<body name='box'><freejoint/><geom type='box' size='.02 .02 .02' pos='.3 0 .02'/></body></worldbody>"
        "<actuator><position joint='slide'/></actuator></mujoco>"
    )
    scene.write_text(
        'schema_version = 1\nmjcf = "model.xml"\n[objects]\nbodies = ["box"]\n[motion]\nduration = 1.0\n'
        '[capture]\nregion = { type = "distance", body = "arm", max = 0.5 }\n'
        '[success]\nregion = { type = "distance", body = "arm", max = 0.1 }\n'
    )
    task = get_task("scene", {"scene_file": str(scene)})
    frames = [task.initial_frame(np.array([[0.3, 0.0, 0.02]]), np.array([[1.0, 0, 0, 0]]), np.ones(2))] * 3
    assert not isinstance(task.capture_regions(frames), FrameRegions)
    with bench.one_region_per_state(True):
        assert isinstance(task.capture_regions(frames), FrameRegions)
    assert not isinstance(task.capture_regions(frames), FrameRegions)
